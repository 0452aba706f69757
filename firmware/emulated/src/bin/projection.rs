//! The projection checks on the emulated Cortex-M7 (QEMU `mps2-an500`).
//!
//! Projects the 9x6 inner corners of the bundled chessboard through the calibrated camera at the
//! first view's pose, logs every pixel with defmt, measures what the projection costs (SysTick,
//! instructions under QEMU `-icount`), shows back-projection and a typed error on the board,
//! checks the answers, and exits through semihosting. `cargo xtask run` runs it before the main
//! job (it is small and quick).
#![no_std]
#![no_main]

use camgeom_fw_emulated::{board, cost};

use core::hint::black_box;

use camgeom::Error;
use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::transform::Pose;
use camgeom_fw_emulated::entry;

use camgeom_fw_emulated::chessboard::{
    COLS, CORNERS, CX, CY, DISTORTION, FX, FY, HEIGHT, OPENCV_PROJECTIONS, RVEC, SQUARE, TVEC,
    WIDTH,
};
use camgeom_fw_emulated::cost::{CostTable, measure};

/// f32 projections must agree with the f64 ones, and with OpenCV's, to this many pixels.
const F32_TOLERANCE_PX: f64 = 0.01;
/// Back-projected rays must agree with the true directions to this angle (radians).
const RAY_TOLERANCE_RAD: f32 = 1e-4;

fn chessboard_camera<T: camgeom::Real>() -> Camera<T> {
    let l = T::lit;
    let k = Intrinsics::new(l(FX), l(FY), l(CX), l(CY));
    let d = Distortion::from_opencv(DISTORTION.map(l));
    match (k, d) {
        (Ok(k), Ok(d)) => Camera::new(k, d),
        (Err(e), _) | (_, Err(e)) => fail("camera", e),
    }
}

fn first_view_pose<T: camgeom::Real>() -> Pose<T> {
    let v = |a: [f64; 3]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));
    Pose::from_rodrigues(v(RVEC), v(TVEC)).unwrap_or_else(|e| fail("pose", e))
}

/// World point of corner `index` (row-major, `i` along the 9 columns).
fn corner<T: camgeom::Real>(index: usize) -> Point3<T> {
    let (i, j) = (index % COLS, index / COLS);
    let l = T::lit;
    Point3::new(l(SQUARE * i as f64), l(SQUARE * j as f64), T::zero())
}

fn fail(what: &str, e: Error) -> ! {
    defmt::error!("{=str}: unexpected error {}", what, e);
    board::exit_failure()
}

fn check(ok: bool, what: &str) {
    if !ok {
        defmt::error!("check failed: {=str}", what);
        board::exit_failure()
    }
}

#[entry]
fn main() -> ! {
    cost::start();
    let mut costs = CostTable::<8>::new();

    // Inputs through black_box: nothing may be computed before the measurement starts.
    let cam: Camera<f32> = black_box(chessboard_camera());
    let pose: Pose<f32> = black_box(first_view_pose());
    let world: [Point3<f32>; CORNERS] = black_box(core::array::from_fn(corner));
    defmt::info!("camera: {}", cam);
    defmt::info!("pose: {}", pose);

    // ---- projection of the 54 corners: the measured loop ----
    let (pixels, projection_cost) = measure(|| {
        let mut out = [Err(Error::NonFinite); CORNERS];
        for (o, p) in out.iter_mut().zip(world.iter()) {
            *o = cam.project(&pose, p);
        }
        out
    });
    costs.record("project", projection_cost, CORNERS as u32);

    // ---- log and check every result against an f64 reference ----
    let cam64: Camera<f64> = chessboard_camera();
    let pose64: Pose<f64> = first_view_pose();
    let mut max_diff = 0.0f64;
    for (index, px) in pixels.iter().enumerate() {
        let (i, j) = (index % COLS, index / COLS);
        match px {
            Ok(px) => {
                defmt::info!(
                    "corner {=usize:02} ({=usize},{=usize}): u = {=f32}, v = {=f32}",
                    index,
                    i,
                    j,
                    px.x,
                    px.y
                );
                check(
                    (0.0..WIDTH).contains(&px.x) && (0.0..HEIGHT).contains(&px.y),
                    "corner inside the image",
                );
                let reference = cam64
                    .project(&pose64, &corner(index))
                    .unwrap_or_else(|e| fail("f64 projection", e));
                let d = (f64::from(px.x) - reference.x)
                    .abs()
                    .max((f64::from(px.y) - reference.y).abs());
                max_diff = max_diff.max(d);
            }
            Err(e) => fail("projection", *e),
        }
    }
    defmt::info!("f32 vs f64 projection: max difference {=f64} px", max_diff);
    check(max_diff <= F32_TOLERANCE_PX, "f32 projection matches f64");
    let mut max_opencv = 0.0f64;
    for (index, u, v) in OPENCV_PROJECTIONS {
        if let Some(Ok(px)) = pixels.get(index) {
            let d = (f64::from(px.x) - u).abs().max((f64::from(px.y) - v).abs());
            max_opencv = max_opencv.max(d);
        } else {
            check(false, "reference corner projected");
        }
    }
    defmt::info!(
        "vs OpenCV projectPoints ({=usize} corners): max difference {=f64} px",
        OPENCV_PROJECTIONS.len(),
        max_opencv
    );
    check(max_opencv <= F32_TOLERANCE_PX, "projection matches OpenCV");

    // ---- undistortion and back-projection of the last corner ----
    let last = CORNERS - 1;
    let pixel = match pixels[last] {
        Ok(p) => p,
        Err(e) => fail("projection", e),
    };
    let ((ray, ideal), back_cost) = measure(|| {
        let pixel = black_box(pixel);
        (cam.back_project(&pixel), cam.undistort_pixel(&pixel))
    });
    costs.record("back-project", back_cost, 1);
    let ray = ray.unwrap_or_else(|e| fail("back-projection", e));
    let ideal = ideal.unwrap_or_else(|e| fail("undistortion", e));
    let xc = pose.apply(&world[last]);
    let truth = xc.coords.normalize();
    // |a x b| = sin(angle) ~ angle for nearby unit vectors.
    let angle = ray.cross(&truth).norm();
    let pinhole = cam
        .intrinsics
        .normalized_to_pixel(&Point2::new(xc.x / xc.z, xc.y / xc.z));
    defmt::info!(
        "undistort corner {=usize}: ({=f32}, {=f32}) -> ideal ({=f32}, {=f32}), pinhole ({=f32}, {=f32})",
        last,
        pixel.x,
        pixel.y,
        ideal.x,
        ideal.y,
        pinhole.x,
        pinhole.y
    );
    defmt::info!(
        "back-project corner {=usize}: ray ({=f32}, {=f32}, {=f32}), {=f32} rad from the true direction",
        last,
        ray.x,
        ray.y,
        ray.z,
        angle
    );
    check(angle <= RAY_TOLERANCE_RAD, "back-projected ray");

    // ---- a typed error on the board: a point 1 m behind the camera ----
    let behind = pose.inverse().apply(&Point3::new(0.0, 0.0, -1.0));
    match cam.project(&pose, &behind) {
        Err(Error::BehindCamera) => {
            defmt::info!(
                "point behind the camera: Err({}) as expected",
                Error::BehindCamera
            )
        }
        Err(e) => fail("point behind the camera", e),
        Ok(p) => {
            defmt::error!(
                "point behind the camera projected to ({=f32}, {=f32})",
                p.x,
                p.y
            );
            board::exit_failure()
        }
    }

    costs.log();
    let (stack, stack_size) = board::stack_usage();
    defmt::info!("stack: {=u32} bytes used of {=u32}", stack, stack_size);
    defmt::info!(
        "projected {=usize} points, cost {=u32} instructions ({=u32} per point)",
        CORNERS,
        projection_cost,
        projection_cost / CORNERS as u32
    );
    board::exit_success()
}
