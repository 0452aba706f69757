//! Undistortion and back-projection over the whole 640x480 image of the bundled camera, in f32
//! (the firmware's type) and f64, and against OpenCV's `undistortPoints`.
//!
//! The OpenCV reference is `data/chessboard/opencv_undistort.csv`, made by
//! `python3 host-tests/scripts/make_fixtures.py` (see data/README.md).

use crate::common::{bundled_camera, chessboard, pixel_grid};
use camgeom::Real;
use camgeom::camera::Camera;
use camgeom::nalgebra::Point2;
use camgeom_host::points::read_csv;

const W: u32 = 640;
const H: u32 = 480;

/// Every pixel of the image (step 1: 307,200 pixels, both borders and all four corners), plus
/// the outer corners of the pixel area, which lie half a pixel further out.
fn whole_image() -> Vec<(f64, f64)> {
    let mut g = pixel_grid(W, H, 1);
    g.extend([(-0.5, -0.5), (639.5, -0.5), (-0.5, 479.5), (639.5, 479.5)]);
    g
}

/// Runs `distort(undistort(p))` over the image; returns the max error (max over u and v), where
/// it happened, and every pixel that failed (error above `tol`, or an `Err`).
fn round_trip<T: Real>(camera: &Camera<T>, tol: f64) -> (f64, (f64, f64), Vec<String>) {
    let mut worst = (0.0f64, (0.0, 0.0));
    let mut failures = Vec::new();
    for (x, y) in whole_image() {
        let p = Point2::new(T::lit(x), T::lit(y));
        let back = camera
            .undistort_pixel(&p)
            .and_then(|ideal| camera.distort_pixel(&ideal));
        match back {
            Ok(b) => {
                let err = (b.x.to_f64() - x).abs().max((b.y.to_f64() - y).abs());
                if err > worst.0 {
                    worst = (err, (x, y));
                }
                if err.is_nan() || err > tol {
                    failures.push(format!("({x}, {y}): error {err:.3e} px"));
                }
            }
            Err(e) => failures.push(format!("({x}, {y}): {e:?}")),
        }
    }
    (worst.0, worst.1, failures)
}

fn report(label: &str, worst: f64, at: (f64, f64), failures: &[String], tol: f64) {
    println!("{label}: max |distort(undistort(p)) - p| = {worst:.3e} px at {at:?}");
    assert!(
        failures.is_empty(),
        "{label}: {} pixels fail the {tol:e} px bound, first ones: {:#?}",
        failures.len(),
        &failures[..failures.len().min(20)]
    );
}

#[test]
fn f32_undistortion_round_trips_over_the_whole_image() {
    let camera = bundled_camera().camera_f32();
    // The firmware's contract: 1e-3 px everywhere in the image. camgeom's Newton iteration stops
    // at a residual of 8 eps max(1, |x_d|) in normalised units (~9.5e-7, i.e. ~5e-4 px at
    // f = 536 px); the conversions pixel <-> normalised add roundings of ~4e-5 px each.
    let tol = 1e-3;
    let (worst, at, failures) = round_trip(&camera, tol);
    report("f32", worst, at, &failures, tol);
}

#[test]
fn f64_undistortion_round_trips_over_the_whole_image() {
    let camera = bundled_camera().camera;
    // Same stopping rule in f64: 8 eps ~ 1.8e-15 normalised, ~1e-12 px; 1e-9 px is a wide margin.
    let tol = 1e-9;
    let (worst, at, failures) = round_trip(&camera, tol);
    report("f64", worst, at, &failures, tol);
}

/// camgeom's `undistort_pixel` against OpenCV's iterative `undistortPoints(..., P=K)` run to
/// convergence (100 iterations, eps 1e-12; the script checked that re-distorting its output gives
/// the input back within 1e-6 px, measured 9e-13 px).
#[test]
fn undistortion_matches_opencv() {
    let t = read_csv(
        chessboard("opencv_undistort.csv"),
        &["u", "v", "u_ideal", "v_ideal"],
    )
    .unwrap();
    // 40-px grid with the last row and column: 17 x 13.
    assert_eq!(t.rows.len(), 17 * 13);
    let spec = bundled_camera();
    let cam64 = spec.camera;
    let cam32 = spec.camera_f32();
    let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
    for r in &t.rows {
        let (x, y, ux, uy) = (r[0], r[1], r[2], r[3]);
        let a = cam64.undistort_pixel(&Point2::new(x, y)).unwrap();
        let e64 = (a.x - ux).abs().max((a.y - uy).abs());
        let b = cam32
            .undistort_pixel(&Point2::new(x as f32, y as f32))
            .unwrap();
        let e32 = (b.x as f64 - ux).abs().max((b.y as f64 - uy).abs());
        assert!(
            e64 < 1e-9,
            "f64 at ({x}, {y}): {a:?} vs ({ux}, {uy}), {e64:e} px"
        );
        assert!(
            e32 < 1e-3,
            "f32 at ({x}, {y}): {b:?} vs ({ux}, {uy}), {e32:e} px"
        );
        worst64 = worst64.max(e64);
        worst32 = worst32.max(e32);
    }
    // f64: both solve the same equation to ~1e-12 px, so 1e-9 px is generous. f32: the ideal
    // pixel is the distorted one moved by the inverse Jacobian times the residual (<= ~5e-4 px,
    // see above), and the Jacobian of this lens stays above ~0.75 inside the image, so the
    // ideal pixel is within ~7e-4 px; the bound is the firmware's 1e-3 px contract.
    println!("vs OpenCV: max error f64 {worst64:.3e} px, f32 {worst32:.3e} px");
}

/// `back_project(p) * s` projects back to `p` for any depth.
fn back_projection_error<T: Real>(camera: &Camera<T>) -> (f64, (f64, f64)) {
    let mut worst = (0.0f64, (0.0, 0.0));
    for (x, y) in pixel_grid(W, H, 4) {
        let p = Point2::new(T::lit(x), T::lit(y));
        let d = camera.back_project(&p).unwrap();
        assert!(d.z > T::zero(), "ray of ({x}, {y}) points backwards");
        assert!((d.norm().to_f64() - 1.0).abs() < 1e-6, "ray not unit");
        for s in [0.05, 0.4, 3.0, 100.0] {
            let xc = d.into_inner() * T::lit(s);
            let uv = camera.project_camera_point(&xc.into()).unwrap();
            let err = (uv.x.to_f64() - x).abs().max((uv.y.to_f64() - y).abs());
            if err > worst.0 {
                worst = (err, (x, y));
            }
        }
    }
    worst
}

#[test]
fn back_projection_round_trips() {
    let spec = bundled_camera();
    let (e32, at32) = back_projection_error(&spec.camera_f32());
    let (e64, at64) = back_projection_error(&spec.camera);
    println!(
        "back-projection: max error f32 {e32:.3e} px at {at32:?}, f64 {e64:.3e} px at {at64:?}"
    );
    // f32: the undistortion error above (<= ~6e-4 px) plus the roundings of normalising the ray,
    // scaling it and dividing by z again (each relative ~6e-8, ~4e-5 px): within 1e-3 px.
    assert!(
        e32 < 1e-3,
        "f32 back-projection error {e32:e} px at {at32:?}"
    );
    assert!(
        e64 < 1e-9,
        "f64 back-projection error {e64:e} px at {at64:?}"
    );
}
