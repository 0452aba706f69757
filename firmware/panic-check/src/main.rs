//! Link-time check that camgeom's firmware entry points cannot panic (the `panic-never`
//! technique): the panic handler below calls a function that exists nowhere, so the link fails
//! with `undefined symbol: camgeom_panic_is_reachable` as soon as any panic path (a failed
//! bounds check, an `unwrap`, an arithmetic overflow check, a `panic!` in a dependency)
//! survives optimisation (release, LTO, one codegen unit). Every input goes through
//! [`black_box`], so the optimiser cannot prove a panic away by knowing the data: what it
//! removes is unreachable for *every* input.
//!
//! One cargo feature per entry point, so a failure names the entry point: `cargo xtask
//! panic-check` builds each and reports; CI links them all in one binary. README "Panic
//! freedom" lists what is covered.
//!
//! Nothing here runs: the binary only has to link.
#![no_std]
#![no_main]
#![allow(unused_imports, dead_code)]

use core::hint::black_box;
use core::panic::PanicInfo;

use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::transform::Pose;
use cortex_m_rt::entry;

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    unsafe extern "Rust" {
        /// Defined nowhere: referencing it makes the link fail.
        fn camgeom_panic_is_reachable() -> !;
    }
    // SAFETY: never called in a binary that links; that is the point of the check.
    unsafe { camgeom_panic_is_reachable() }
}

/// Frame size for the image entry points (the value is opaque to the optimiser anyway).
const W: usize = 64;
const H: usize = 48;

fn camera() -> Option<Camera<f32>> {
    let [fx, fy, cx, cy, s] = black_box([300.0f32, 300.0, 31.5, 23.5, 0.0]);
    let k = Intrinsics::with_skew(fx, fy, cx, cy, s).ok()?;
    let d = Distortion::from_opencv(black_box([0.1f32, -0.05, 0.0, 0.0, 0.0])).ok()?;
    Some(Camera::new(k, d))
}

fn pose() -> Option<Pose<f32>> {
    Pose::from_rodrigues(
        black_box(Vector3::new(0.1f32, -0.2, 0.05)),
        black_box(Vector3::new(0.0f32, 0.0, 1.0)),
    )
    .ok()
}

#[cfg(feature = "camera")]
fn run_camera() {
    let Some(cam) = camera() else { return };
    let Some(pose) = pose() else { return };
    let x = black_box(Point3::new(0.1f32, 0.2, 0.3));
    black_box(cam.project(&pose, &x).ok());
    let u = black_box(Point2::new(10.0f32, 20.0));
    black_box(cam.back_project(&u).ok());
    black_box(cam.undistort_pixel(&u).ok());
    black_box(cam.distort_pixel(&u).ok());
}

#[cfg(feature = "pyramid")]
fn run_pyramid() {
    use camgeom::image::ImageView;
    use camgeom::pyramid::Pyramid;
    let frame = black_box([0u8; W * H]);
    let mut buf = black_box([0u8; W * H]);
    let (w, h, s, levels) = black_box((W, H, W, 4usize));
    let Ok(view) = ImageView::new(black_box(&frame[..]), w, h, s) else {
        return;
    };
    if let Ok(p) = Pyramid::build(view, black_box(&mut buf[..]), levels) {
        black_box(p.level(black_box(2)));
    }
}

#[cfg(feature = "good_features")]
fn run_good_features() {
    use camgeom::corners::{Corner, CornerConfig, good_features};
    use camgeom::heapless::Vec;
    use camgeom::image::ImageView;
    let frame = black_box([0u8; W * H]);
    let (w, h, s) = black_box((W, H, W));
    let Ok(view) = ImageView::new(black_box(&frame[..]), w, h, s) else {
        return;
    };
    let mut candidates = black_box([Corner::default(); 64]);
    let mut scratch = black_box([0u32; 6 * W]);
    let existing = black_box([[3i32, 4]; 4]);
    let cfg = black_box(CornerConfig::default());
    let mut out: Vec<Corner, 32> = Vec::new();
    black_box(
        good_features(
            &view,
            &cfg,
            black_box(&existing[..]).iter().copied(),
            &mut out,
            black_box(&mut candidates[..]),
            black_box(&mut scratch[..]),
        )
        .ok(),
    );
    black_box(&out);
}

#[cfg(feature = "calc_flow_fixed")]
fn run_calc_flow_fixed() {
    use camgeom::image::ImageView;
    use camgeom::klt::{Fixed, Flow, Gradients, LkConfig, calc_flow};
    use camgeom::pyramid::Pyramid;
    let a = black_box([0u8; W * H]);
    let b = black_box([0u8; W * H]);
    let mut pa_buf = black_box([0u8; W * H]);
    let mut pb_buf = black_box([0u8; W * H]);
    let (w, h, levels) = black_box((W, H, 3usize));
    let (Ok(va), Ok(vb)) = (
        ImageView::packed(black_box(&a[..]), w, h),
        ImageView::packed(black_box(&b[..]), w, h),
    ) else {
        return;
    };
    let (Ok(pa), Ok(pb)) = (
        Pyramid::build(va, black_box(&mut pa_buf[..]), levels),
        Pyramid::build(vb, black_box(&mut pb_buf[..]), levels),
    ) else {
        return;
    };
    let pts = black_box([[10i32 << 16, 12 << 16]; 8]);
    let mut flows = black_box([Flow::<i32>::default(); 8]);
    let mut scratch = black_box([0i16; 4096]);
    let Ok(cfg) = black_box(LkConfig::default()).check() else {
        return;
    };
    black_box(
        calc_flow::<Fixed>(
            &pa,
            &pb,
            black_box(&pts[..]),
            black_box(&mut flows[..]),
            &cfg,
            Gradients::PerWindow,
            black_box(&mut scratch[..]),
        )
        .ok(),
    );
    black_box(&flows);
}

#[cfg(feature = "find_homography")]
fn run_find_homography() {
    use camgeom::homography::find_homography;
    use camgeom::ransac::RansacConfig;
    let src = black_box([Point2::new(1.0f32, 2.0); 16]);
    let dst = black_box([Point2::new(3.0f32, 4.0); 16]);
    let mut mask = black_box([false; 16]);
    let cfg = black_box(RansacConfig::<f32>::default());
    black_box(
        find_homography(
            black_box(&src[..]),
            black_box(&dst[..]),
            &cfg,
            black_box(&mut mask[..]),
        )
        .ok(),
    );
}

#[cfg(feature = "solve_planar")]
fn run_solve_planar() {
    use camgeom::pose::{PlanarConfig, solve_planar};
    let Some(cam) = camera() else { return };
    let model = black_box([Point2::new(0.1f32, 0.2); 16]);
    let pixels = black_box([Point2::new(3.0f32, 4.0); 16]);
    let mut scratch = black_box([Point2::new(0.0f32, 0.0); 16]);
    let cfg = black_box(PlanarConfig::default());
    black_box(
        solve_planar(
            &cam,
            black_box(&model[..]),
            black_box(&pixels[..]),
            black_box(&mut scratch[..]),
            &cfg,
        )
        .ok(),
    );
}

#[cfg(feature = "draw_wireframe")]
fn run_draw_wireframe() {
    use camgeom::draw::{WireframeConfig, cube, draw_wireframe};
    use camgeom::image::ImageMut;
    let Some(cam) = camera() else { return };
    let Some(pose) = pose() else { return };
    let mut frame = black_box([0u8; W * H]);
    let (w, h, s) = black_box((W, H, W));
    let Ok(mut img) = ImageMut::new(black_box(&mut frame[..]), w, h, s) else {
        return;
    };
    let (vertices, edges) = black_box(cube(0.05f32, 0.025, 0.1));
    let cfg = black_box(WireframeConfig::default());
    black_box(
        draw_wireframe(
            &mut img,
            &cam,
            &pose,
            black_box(&vertices[..]),
            black_box(&edges[..]),
            &cfg,
        )
        .ok(),
    );
}

#[cfg(feature = "target_step")]
fn run_target_step() {
    use camgeom::image::ImageView;
    use camgeom::klt::Fixed;
    use camgeom::pyramid::Pyramid;
    use camgeom::target::{
        GivenCorners, PlanarTarget, TargetConfig, TargetParams, corner_scratch_len,
        flow_scratch_len,
    };
    let Some(cam) = camera() else { return };
    let a = black_box([0u8; W * H]);
    let b = black_box([0u8; W * H]);
    let mut pa_buf = black_box([0u8; W * H]);
    let mut pb_buf = black_box([0u8; W * H]);
    let (w, h, levels) = black_box((W, H, 3usize));
    let (Ok(va), Ok(vb)) = (
        ImageView::packed(black_box(&a[..]), w, h),
        ImageView::packed(black_box(&b[..]), w, h),
    ) else {
        return;
    };
    let cfg = black_box(TargetConfig::default());
    let size = black_box([0.2f32, 0.15f32]);
    let Ok(params) = TargetParams::new(&cfg, cam, size) else {
        return;
    };
    let mut target = black_box(PlanarTarget::<
        Fixed,
        32,
        { flow_scratch_len(15) },
        { corner_scratch_len(W) },
        64,
    >::new());
    let mut acquire = GivenCorners::new(black_box([
        Point2::new(10.0f32, 10.0),
        Point2::new(50.0, 10.0),
        Point2::new(50.0, 40.0),
        Point2::new(10.0, 40.0),
    ]));
    let (Ok(pa), Ok(pb)) = (
        Pyramid::build(va, black_box(&mut pa_buf[..]), levels),
        Pyramid::build(vb, black_box(&mut pb_buf[..]), levels),
    ) else {
        return;
    };
    black_box(target.step(&params, None, &pa, &mut acquire, &mut ()).ok());
    black_box(
        target
            .step(&params, Some(&pa), &pb, &mut acquire, &mut ())
            .ok(),
    );
}

#[cfg(not(any(
    feature = "camera",
    feature = "pyramid",
    feature = "good_features",
    feature = "calc_flow_fixed",
    feature = "find_homography",
    feature = "solve_planar",
    feature = "draw_wireframe",
    feature = "target_step"
)))]
fn run() {}

#[entry]
fn main() -> ! {
    // Each feature adds one entry point; with several, the binary links only if none of them
    // has a panic path.
    #[cfg(feature = "camera")]
    run_camera();
    #[cfg(feature = "pyramid")]
    run_pyramid();
    #[cfg(feature = "good_features")]
    run_good_features();
    #[cfg(feature = "calc_flow_fixed")]
    run_calc_flow_fixed();
    #[cfg(feature = "find_homography")]
    run_find_homography();
    #[cfg(feature = "solve_planar")]
    run_solve_planar();
    #[cfg(feature = "draw_wireframe")]
    run_draw_wireframe();
    #[cfg(feature = "target_step")]
    run_target_step();
    loop {
        core::hint::spin_loop();
    }
}
