//! Calibration and chessboard detection in the core: typed errors for every bad input, the
//! unobservability warning, and property tests (calibration round trip through both lens
//! models, fisheye projection / undistortion round trip). The comparisons with OpenCV on real
//! and rendered data are in `host-tests/tests/it/calib_*.rs`.

use camgeom::Error;
use camgeom::calib::{CalibrationConfig, CalibrationParams, CalibrationWarning, Calibrator};
use camgeom::camera::{Camera, Distortion, Fisheye, Intrinsics, Lens, LensModel};
use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SaddleConfig, SaddleParams,
    saddle_subpix, scratch_len,
};
use camgeom::image::ImageView;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::rng::Pcg32;
use camgeom::transform::Pose;
use proptest::prelude::*;

const COLS: usize = 8;
const ROWS: usize = 5;
const SQUARE: f64 = 0.03;

fn board() -> BoardSize {
    BoardSize::new(COLS, ROWS).unwrap()
}

fn brown() -> Camera<f64> {
    Camera::new(
        Intrinsics::new(610.0, 605.0, 318.0, 243.0).unwrap(),
        Distortion::from_opencv([-0.28, 0.09, 0.0008, -0.0004, -0.01]).unwrap(),
    )
}

/// The board's corners through `camera` at `pose`, `None` when one leaves the 640x480 frame.
fn view(camera: &Camera<f64>, pose: &Pose<f64>) -> Option<Vec<Point2<f64>>> {
    (0..COLS * ROWS)
        .map(|k| {
            let x = Point3::new(SQUARE * (k % COLS) as f64, SQUARE * (k / COLS) as f64, 0.0);
            camera
                .project(pose, &x)
                .ok()
                .filter(|u| u.x > 5.0 && u.y > 5.0 && u.x < 635.0 && u.y < 475.0)
        })
        .collect()
}

/// A pose looking at the board's centre, tilted by `tilt` (radians) about a
/// random axis in the board plane, rolled by up to 0.5 rad, 0.3..0.45 m away.
fn pose(g: &mut Pcg32, tilt: f64) -> Pose<f64> {
    let roll = g.uniform(-0.5, 0.5);
    let dist = g.uniform(0.3, 0.45);
    let a = g.uniform(0.0, std::f64::consts::TAU);
    let r = Vector3::new(tilt * a.cos(), tilt * a.sin(), roll);
    let rot = camgeom::nalgebra::Rotation3::new(r);
    let centre = Vector3::new(
        SQUARE * (COLS - 1) as f64 / 2.0,
        SQUARE * (ROWS - 1) as f64 / 2.0,
        0.0,
    );
    let shift = Vector3::new(g.uniform(-0.03, 0.03), g.uniform(-0.02, 0.02), dist);
    Pose::new(rot, shift - rot * centre).unwrap()
}

fn views(
    camera: &Camera<f64>,
    n: usize,
    tilt: f64,
    seed: u64,
    noise: f64,
) -> Vec<Vec<Point2<f64>>> {
    let mut g = Pcg32::new(seed);
    let mut out = vec![];
    while out.len() < n {
        let p = pose(&mut g, tilt);
        if let Some(mut v) = view(camera, &p) {
            for u in v.iter_mut() {
                // Box-Muller from the generator: Gaussian pixel noise.
                let (a, b) = (g.uniform(1e-12, 1.0), g.uniform(0.0, std::f64::consts::TAU));
                let r = (-2.0 * a.ln()).sqrt() * noise;
                *u += Vector3::new(r * b.cos(), r * b.sin(), 0.0).xy();
            }
            out.push(v);
        }
    }
    out
}

fn calibrator(vs: &[Vec<Point2<f64>>]) -> Box<Calibrator<f64, 16, 40>> {
    let mut cal = Box::new(Calibrator::new(board(), SQUARE, 640, 480).unwrap());
    for v in vs {
        cal.add_view(640, 480, v).unwrap();
    }
    cal
}

#[test]
fn bad_input_is_a_typed_error() {
    let b = board();
    for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert_eq!(
            Calibrator::<f64, 4, 40>::new(b, s, 640, 480).err(),
            Some(Error::InvalidParameter("square"))
        );
    }
    assert_eq!(
        Calibrator::<f64, 4, 39>::new(b, SQUARE, 640, 480).err(),
        Some(Error::BufferTooSmall("corners"))
    );
    assert_eq!(
        Calibrator::<f64, 4, 40>::new(b, SQUARE, 0, 480).err(),
        Some(Error::InvalidImage)
    );
    let vs = views(&brown(), 4, 0.5, 1, 0.0);
    let mut cal = Box::new(Calibrator::<f64, 3, 40>::new(b, SQUARE, 640, 480).unwrap());
    assert_eq!(cal.add_view(320, 240, &vs[0]), Err(Error::InvalidImage));
    assert_eq!(
        cal.add_view(640, 480, &vs[0][..39]),
        Err(Error::LengthMismatch)
    );
    let mut nan = vs[0].clone();
    nan[7].x = f64::NAN;
    assert_eq!(cal.add_view(640, 480, &nan), Err(Error::NonFinite));
    cal.add_view(640, 480, &vs[0]).unwrap();
    cal.add_view(640, 480, &vs[1]).unwrap();
    // Two views: too few.
    assert_eq!(
        cal.solve(&CalibrationParams::default()).err(),
        Some(Error::TooFewPoints)
    );
    cal.add_view(640, 480, &vs[2]).unwrap();
    assert_eq!(
        cal.add_view(640, 480, &vs[3]),
        Err(Error::BufferTooSmall("views"))
    );
    let bad = CalibrationConfig {
        max_iterations: 0,
        ..CalibrationConfig::default()
    };
    assert_eq!(
        bad.check().and_then(|p| cal.solve(&p)).err(),
        Some(Error::InvalidParameter("max_iterations"))
    );
    let mut bad = CalibrationConfig::default();
    bad.flags.fix_aspect_ratio = Some(f64::NAN);
    assert_eq!(
        bad.check().and_then(|p| cal.solve(&p)).err(),
        Some(Error::InvalidParameter("flags.fix_aspect_ratio"))
    );
    // Three views that are all parallel to the image plane: the focal length is not
    // determined by them.
    let mut g = Pcg32::new(3);
    let parallel: Vec<_> = (0..4)
        .map(|_| view(&brown(), &pose(&mut g, 0.0)).unwrap())
        .collect();
    assert_eq!(
        calibrator(&parallel)
            .solve(&CalibrationParams::default())
            .err(),
        Some(Error::Degenerate)
    );
}

#[test]
fn nearly_fronto_parallel_views_warn_that_the_focal_length_is_free() {
    let mut cfg = CalibrationConfig::default();
    cfg.flags.zero_tangent = true;
    cfg.flags.fix_k3 = true;
    // 1.5° of tilt and 0.3 px of noise: the closed form finds no camera at all.
    let vs = views(&brown(), 8, 0.026, 5, 0.3);
    assert_eq!(
        calibrator(&vs).solve(&cfg.check().unwrap()).err(),
        Some(Error::Degenerate)
    );
    // 4.6°: a camera, but its focal length is uncertain by more than 5 % (measured 5.4 %).
    let vs = views(&brown(), 8, 0.08, 5, 0.3);
    let r = calibrator(&vs).solve(&cfg.check().unwrap()).unwrap();
    assert!(
        r.warnings
            .contains(&CalibrationWarning::FocalLengthUnconstrained),
        "{r:?}"
    );
    assert!(r.std[0] > 0.05 * r.camera.intrinsics.fx());
    // The same camera seen at 30°: no warning.
    let vs = views(&brown(), 8, 0.5, 5, 0.3);
    let r = calibrator(&vs).solve(&cfg.check().unwrap()).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

#[test]
fn flags_hold_their_parameters() {
    let vs = views(&brown(), 10, 0.5, 9, 0.2);
    let mut cfg = CalibrationConfig::default();
    cfg.flags.fix_principal_point = true;
    cfg.flags.zero_tangent = true;
    cfg.flags.fix_k3 = true;
    cfg.flags.fix_aspect_ratio = Some(1.0);
    let r = calibrator(&vs).solve(&cfg.check().unwrap()).unwrap();
    let k = &r.camera.intrinsics;
    assert_eq!(k.fx(), k.fy());
    assert!((k.cx() - 319.5).abs() < 1e-9 && (k.cy() - 239.5).abs() < 1e-9);
    let Lens::BrownConrady(d) = r.camera.lens else {
        panic!("not a Brown-Conrady camera: {:?}", r.camera.lens)
    };
    assert_eq!((d.p1, d.p2, d.k3), (0.0, 0.0, 0.0));
    assert_eq!(
        (r.std[2], r.std[3], r.std[6], r.std[7], r.std[8]),
        (0.0, 0.0, 0.0, 0.0, 0.0)
    );
}

#[test]
fn detector_errors_and_negatives() {
    let px = vec![128u8; 64 * 48];
    let img = ImageView::packed(&px, 64, 48).unwrap();
    let mut det = Box::new(ChessboardDetector::<64>::new());
    let mut scratch = vec![0i32; scratch_len(64)];
    let cfg = DetectConfig::default();
    let params = cfg.check().unwrap();
    let b = BoardSize::new(4, 3).unwrap();
    assert_eq!(
        det.detect::<11>(&img, b, &params, &mut scratch).err(),
        Some(Error::BufferTooSmall("corners"))
    );
    assert_eq!(
        det.detect::<12>(&img, b, &params, &mut scratch[..100])
            .err(),
        Some(Error::BufferTooSmall("scratch"))
    );
    let tiny = ImageView::packed(&px[..15 * 15], 15, 15).unwrap();
    assert_eq!(
        det.detect::<12>(&tiny, b, &params, &mut scratch).err(),
        Some(Error::InvalidImage)
    );
    let bad = DetectConfig {
        max_seeds: 0,
        ..cfg
    };
    assert_eq!(
        bad.check().err(),
        Some(Error::InvalidParameter("max_seeds"))
    );
    assert_eq!(
        BoardSize::new(2, 5).err(),
        Some(Error::InvalidParameter("board.cols"))
    );
    let bad = DetectConfig {
        refine: Refinement::Saddle(SaddleConfig {
            sigma: 0.1,
            ..SaddleConfig::default()
        }),
        ..cfg
    };
    assert_eq!(
        bad.check().err(),
        Some(Error::InvalidParameter("saddle.sigma"))
    );
    let mut nan = [Point2::new(f32::NAN, 1.0)];
    assert_eq!(
        saddle_subpix(&img, &mut nan, &SaddleParams::default()),
        Err(Error::NonFinite)
    );
    // A flat frame and a noise frame hold no board.
    assert_eq!(det.detect::<12>(&img, b, &params, &mut scratch), Ok(None));
    let mut g = Pcg32::new(1);
    let noise: Vec<u8> = (0..64 * 48).map(|_| g.uniform(0.0, 255.0) as u8).collect();
    let img = ImageView::packed(&noise, 64, 48).unwrap();
    assert_eq!(det.detect::<12>(&img, b, &params, &mut scratch), Ok(None));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Project with a known camera, calibrate, recover it (noise-free: the truth is the
    /// minimum; 1e-5 px / 1e-6 leave orders of magnitude over the f64 solve's rounding).
    #[test]
    fn calibration_round_trip(
        f in 400.0f64..900.0, aspect in 0.97f64..1.03, c in prop::array::uniform2(-20.0f64..20.0),
        k1 in -0.35f64..0.1, k2 in -0.1f64..0.15, seed in 0u64..1000, fisheye in any::<bool>(),
    ) {
        let k = Intrinsics::new(f, f * aspect, 319.5 + c[0], 239.5 + c[1]).unwrap();
        let (cam, kind) = if fisheye {
            (Camera::fisheye(k, Fisheye::from_opencv([k1 * 0.2, k2 * 0.1, 0.0, 0.0]).unwrap()), LensModel::KannalaBrandt)
        } else {
            (Camera::new(k, Distortion::from_opencv([k1, k2, 0.0, 0.0, 0.0]).unwrap()), LensModel::BrownConrady)
        };
        let vs = views(&cam, 8, 0.6, seed, 0.0);
        let mut cfg = CalibrationConfig { model: kind, max_iterations: 100, ..CalibrationConfig::default() };
        cfg.flags.zero_tangent = true;
        cfg.flags.fix_k3 = true;
        cfg.flags.fix_k4 = true;
        let r = calibrator(&vs).solve(&cfg.check().unwrap()).unwrap();
        prop_assert!(r.rms_px < 1e-5, "rms {}", r.rms_px);
        let e = &r.camera.intrinsics;
        prop_assert!((e.fx() - k.fx()).abs() < 1e-4 && (e.fy() - k.fy()).abs() < 1e-4);
        prop_assert!((e.cx() - k.cx()).abs() < 1e-4 && (e.cy() - k.cy()).abs() < 1e-4);
        prop_assert_eq!(r.views_used, 8);
    }

    /// Fisheye projection and back-projection invert each other over the whole model range
    /// up to 80° off the axis.
    #[test]
    fn fisheye_project_undistort_round_trip(
        theta in 0.0f64..1.4, phi in 0.0f64..std::f64::consts::TAU,
        k in prop::array::uniform4(-0.02f64..0.02), f32_path in any::<bool>(),
    ) {
        let cam = Camera::fisheye(
            Intrinsics::new(280.0, 282.0, 320.0, 240.0).unwrap(),
            Fisheye::from_opencv(k).unwrap(),
        );
        // Only where the lens is one to one: θ_d(t) increasing on [0, θ] (beyond a fold two
        // angles share an image, and back-projection gives the one nearer the axis).
        let slope = |t: f64| {
            let t2 = t * t;
            1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))
        };
        prop_assume!((0..=100).all(|i| slope(theta * i as f64 / 100.0) > 0.05));
        let ray = Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
        let xc = Point3::from(ray * 2.0);
        if f32_path {
            let c = cam.cast::<f32>();
            let u = c.project_camera_point(&xc.cast::<f32>()).unwrap();
            let back = c.back_project(&u).unwrap();
            // f32: the ray to 1e-4 rad at 80° (tan θ amplifies the rounding of θ).
            prop_assert!((back.into_inner().cast::<f64>() - ray).amax() < 1e-4);
        } else {
            let u = cam.project_camera_point(&xc).unwrap();
            let back = cam.back_project(&u).unwrap();
            prop_assert!((back.into_inner() - ray).amax() < 1e-10);
        }
    }
}

/// Existing entry points taking a `Camera` follow its lens model: planar pose (IPPE on
/// fisheye-undistorted rays, LM through the fisheye Jacobian) recovers a pose seen through a
/// wide fisheye lens exactly.
#[test]
fn pose_solvers_follow_the_fisheye_model() {
    use camgeom::pose::{PlanarConfig, solve_planar};
    let cam = Camera::fisheye(
        Intrinsics::new(250.0, 251.0, 321.0, 239.0).unwrap(),
        Fisheye::from_opencv([0.05, -0.02, 0.01, -0.003]).unwrap(),
    );
    let mut g = Pcg32::new(21);
    let mut tested = 0;
    for _ in 0..5 {
        let truth = pose(&mut g, 0.7);
        let Some(pixels) = view(&cam, &truth) else {
            continue;
        };
        tested += 1;
        let model: Vec<Point2<f64>> = (0..COLS * ROWS)
            .map(|k| Point2::new(SQUARE * (k % COLS) as f64, SQUARE * (k / COLS) as f64))
            .collect();
        let mut scratch = vec![Point2::origin(); model.len()];
        let p = solve_planar(
            &cam,
            &model,
            &pixels,
            &mut scratch,
            &PlanarConfig::default(),
        )
        .unwrap();
        // Noise-free: the refined pose is the truth to the f64 solve's rounding (1e-9 rad,
        // 1e-9 m leave three orders of magnitude).
        // Through the unit quaternions: the trace of a product of rotation matrices can exceed
        // 3 by rounding, and its acos is then NaN.
        let dr = crate::common::rot_err(&p.best.pose, &truth).to_radians();
        let dt = (p.best.pose.translation() - truth.translation()).norm();
        assert!(dr < 1e-9 && dt < 1e-9, "{dr} {dt}");
        assert!(p.best.rms_px < 1e-8);
    }
    assert!(tested >= 3, "{tested} poses in view");
}

/// Partial views of a board of identified points: each view keeps only the corners inside the
/// frame (poses close enough that none shows the whole 14x10 board) and drops a random third
/// of the rest; the camera comes back exactly. A view of 3 points and one of a single row
/// are rejected with their reasons, and bad ids are typed errors.
#[test]
fn partial_views_of_identified_points_calibrate() {
    const C: usize = 14;
    const R: usize = 10;
    let pts: Vec<Point2<f64>> = (0..C * R)
        .map(|k| Point2::new(SQUARE * (k % C) as f64, SQUARE * (k / C) as f64))
        .collect();
    let cam = brown();
    let mut cal =
        Box::new(Calibrator::<f64, 16, 140>::with_points(&pts, SQUARE, 640, 480).unwrap());
    let mut g = Pcg32::new(7);
    let mut added = 0;
    while added < 10 {
        let roll = g.uniform(-0.5, 0.5);
        let a = g.uniform(0.0, std::f64::consts::TAU);
        let tilt = g.uniform(0.2, 0.6);
        let rot =
            camgeom::nalgebra::Rotation3::new(Vector3::new(tilt * a.cos(), tilt * a.sin(), roll));
        let target = Vector3::new(g.uniform(0.05, 0.34), g.uniform(0.05, 0.22), 0.0);
        let pose = Pose::new(
            rot,
            Vector3::new(0.0, 0.0, g.uniform(0.25, 0.35)) - rot * target,
        )
        .unwrap();
        let (mut ids, mut px) = (vec![], vec![]);
        let mut all = true;
        for (k, p) in pts.iter().enumerate() {
            let u = cam.project(&pose, &Point3::new(p.x, p.y, 0.0)).ok();
            match u.filter(|u| u.x > 0.0 && u.y > 0.0 && u.x < 639.0 && u.y < 479.0) {
                Some(u) if g.uniform(0.0, 1.0) > 0.33 => {
                    ids.push(k);
                    px.push(u);
                }
                Some(_) => {}
                None => all = false,
            }
        }
        if all || ids.len() < 20 {
            continue;
        }
        cal.add_points(640, 480, &ids, &px).unwrap();
        added += 1;
    }
    // Rejected views: 3 points, then 8 points of one row.
    let few: Vec<usize> = vec![0, 1, 15];
    let px: Vec<Point2<f64>> = few
        .iter()
        .map(|&k| Point2::new(10.0 + k as f64, 20.0))
        .collect();
    cal.add_points(640, 480, &few, &px).unwrap();
    let row: Vec<usize> = (0..8).collect();
    let px: Vec<Point2<f64>> = row
        .iter()
        .map(|&k| Point2::new(10.0 + 9.0 * k as f64, 20.0))
        .collect();
    cal.add_points(640, 480, &row, &px).unwrap();
    let report = cal.solve(&CalibrationParams::default()).unwrap();
    assert!(report.rms_px < 1e-6, "{}", report.rms_px);
    let k = report.camera.intrinsics;
    assert!(
        (k.fx() - 610.0).abs() < 1e-4 && (k.cy() - 243.0).abs() < 1e-4,
        "{k:?}"
    );
    assert_eq!(report.views_used, 10);
    assert_eq!(
        report.rejections[10],
        Some(camgeom::calib::ViewRejection::TooFewPoints)
    );
    assert_eq!(
        report.rejections[11],
        Some(camgeom::calib::ViewRejection::Degenerate)
    );
    assert_eq!(report.rejected().collect::<Vec<_>>(), vec![10, 11]);
    // Typed errors.
    let p = [Point2::new(1.0, 1.0); 2];
    assert_eq!(
        cal.add_points(640, 480, &[0, 0], &p),
        Err(Error::InvalidParameter("ids"))
    );
    assert_eq!(
        cal.add_points(640, 480, &[0, 140], &p),
        Err(Error::InvalidParameter("ids"))
    );
    assert_eq!(
        cal.add_points(640, 480, &[0], &p),
        Err(Error::LengthMismatch)
    );
    assert_eq!(
        cal.add_points(64, 480, &[0, 1], &p),
        Err(Error::InvalidImage)
    );
    assert_eq!(
        Calibrator::<f64, 4, 3>::with_points(&pts[..4], SQUARE, 640, 480).err(),
        Some(Error::BufferTooSmall("corners"))
    );
    assert_eq!(
        Calibrator::<f64, 4, 8>::with_points(&pts[..3], SQUARE, 640, 480).err(),
        Some(Error::TooFewPoints)
    );
}
