//! Link-time check that camgeom's public no_std entry points cannot panic (the `panic-never`
//! technique): the panic handler below calls a function that exists nowhere, so the link fails
//! with `undefined symbol: camgeom_panic_is_reachable` as soon as any panic path (a failed
//! bounds check, an `unwrap`, an arithmetic overflow check, a `panic!` in a dependency)
//! survives optimisation (release, LTO, one codegen unit). Every input goes through
//! [`black_box`], so the optimiser cannot prove a panic away by knowing the data: what it
//! removes is unreachable for *every* input.
//!
//! One cargo feature per module of the core (`camera`, `klt`, `twoview`, ...), so a failure
//! names the area, and one per scalar type: `f32` instantiates every entry point (the integer
//! and `f32`-only ones with it), `f64` the generic ones again with `f64`. `cargo xtask
//! panic-check` links each area with each scalar type on `thumbv7em-none-eabihf` and
//! `thumbv6m-none-eabi` and prints the table; CI links them all in one binary per target.
//! README "Panic freedom" lists what is covered.
//!
//! Nothing here runs: the binary only has to link.
#![no_std]
#![no_main]
#![allow(unused_imports, dead_code)]

use core::hint::black_box;
use core::panic::PanicInfo;

use camgeom::Real;
use camgeom::camera::{Camera, Distortion, Fisheye, Intrinsics};
use camgeom::image::{ImageMut, ImageView};
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::pyramid::Pyramid;
use camgeom::ransac::{RansacConfig, RansacParams};
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
/// Point counts of the point-set entry points.
const N: usize = 16;

fn lit<T: Real>(v: f64) -> T {
    T::lit(v)
}

fn pt2<T: Real>(x: f64, y: f64) -> Point2<T> {
    Point2::new(lit(x), lit(y))
}

fn pt3<T: Real>(x: f64, y: f64, z: f64) -> Point3<T> {
    Point3::new(lit(x), lit(y), lit(z))
}

fn intrinsics<T: Real>() -> Option<Intrinsics<T>> {
    let [fx, fy, cx, cy, s] = black_box([300.0, 300.0, 31.5, 23.5, 0.0].map(lit::<T>));
    Intrinsics::with_skew(fx, fy, cx, cy, s).ok()
}

/// A Brown-Conrady camera.
fn camera<T: Real>() -> Option<Camera<T>> {
    let d = Distortion::from_opencv(black_box([0.1, -0.05, 0.0, 0.0, 0.0].map(lit::<T>))).ok()?;
    Some(Camera::new(intrinsics()?, d))
}

/// A Kannala-Brandt camera.
fn fisheye<T: Real>() -> Option<Camera<T>> {
    let f = Fisheye::from_opencv(black_box([0.1, -0.01, 0.0, 0.0].map(lit::<T>))).ok()?;
    Some(Camera::fisheye(intrinsics()?, f))
}

fn pose<T: Real>() -> Option<Pose<T>> {
    Pose::from_rodrigues(
        black_box(Vector3::new(lit(0.1), lit(-0.2), lit(0.05))),
        black_box(Vector3::new(lit(0.0), lit(0.0), lit(1.0))),
    )
    .ok()
}

fn points2<T: Real, const M: usize>() -> [Point2<T>; M] {
    black_box([pt2(1.0, 2.0); M])
}

fn points3<T: Real, const M: usize>() -> [Point3<T>; M] {
    black_box([pt3(0.1, 0.2, 1.0); M])
}

/// RANSAC parameters checked from an opaque configuration (the default ones if it fails), so
/// the check is linked too.
fn ransac_params<T: Real>() -> RansacParams<T> {
    black_box(RansacConfig::default())
        .check()
        .unwrap_or_default()
}

/// A `W`x`H` frame over `buf`, the geometry opaque.
fn view(buf: &[u8]) -> Option<ImageView<'_, u8>> {
    let (w, h, s) = black_box((W, H, W));
    ImageView::new(black_box(buf), w, h, s).ok()
}

/// Two 3-level pyramids of opaque `W`x`H` frames, handed to `f`.
#[cfg(feature = "target")]
fn two_pyramids(f: impl FnOnce(&Pyramid<'_>, &Pyramid<'_>)) {
    let a = black_box([0u8; W * H]);
    let b = black_box([0u8; W * H]);
    let mut pa_buf = black_box([0u8; W * H]);
    let mut pb_buf = black_box([0u8; W * H]);
    let (Some(va), Some(vb)) = (view(&a), view(&b)) else {
        return;
    };
    let levels = black_box(3usize);
    if let (Ok(pa), Ok(pb)) = (
        Pyramid::build(va, black_box(&mut pa_buf[..]), levels),
        Pyramid::build(vb, black_box(&mut pb_buf[..]), levels),
    ) {
        f(&pa, &pb);
    }
}

/// A `W`x`H` output image over `buf`, the geometry opaque.
fn image_mut(buf: &mut [u8]) -> Option<ImageMut<'_, u8>> {
    let (w, h, s) = black_box((W, H, W));
    ImageMut::new(black_box(buf), w, h, s).ok()
}

// ---------------------------------------------------------------- camera

/// Projection and back-projection through both lens models, and the jacobians.
#[cfg(feature = "camera")]
fn run_camera<T: Real>() {
    let Some(pose) = pose::<T>() else { return };
    for cam in [camera::<T>(), fisheye::<T>()].into_iter().flatten() {
        let cam = black_box(cam);
        let x = black_box(pt3(0.1, 0.2, 0.3));
        black_box(cam.project(&pose, &x).ok());
        black_box(cam.project_camera_point(&x).ok());
        black_box(cam.project_with_jacobian(&x).ok());
        black_box(cam.project_with_parameter_jacobian(&x).ok());
        let world = points3::<T, N>();
        let mut out = black_box([Err(camgeom::Error::NonFinite); N]);
        black_box(cam.project_points(&pose, &world, &mut out).ok());
        black_box(&out);
        let u = black_box(pt2(10.0, 20.0));
        black_box(cam.back_project(&u).ok());
        black_box(cam.undistort_pixel(&u).ok());
        black_box(cam.undistort_to_normalized(&u).ok());
        black_box(cam.distort_pixel(&u).ok());
        black_box(cam.distort_normalized(&u).ok());
        black_box(cam.undistort_normalized(&u).ok());
        black_box(cam.lens.model());
    }
}

// ---------------------------------------------------------------- fixed

/// Q16.16 homography transfer and projection, built from `T`.
#[cfg(feature = "fixed")]
fn run_fixed<T: Real>() {
    use camgeom::fixed::{FixedHomography, FixedProjection, Q16};
    use camgeom::nalgebra::Matrix3;
    let x = black_box([Q16::from_bits(3 << 16), Q16::from_bits(-5 << 16)]);
    let m = black_box(Matrix3::from_element(lit::<T>(0.5)));
    if let Ok(h) = FixedHomography::from_matrix(&m) {
        black_box(h.transfer(&x).ok());
    }
    let parts = black_box([[lit::<T>(1.0); 2]; 3]);
    if let Ok(h) = FixedHomography::from_parts(&parts, &black_box([lit::<T>(0.5); 3])) {
        black_box(h.transfer(&x).ok());
    }
    let (Some(k), Some(pose)) = (intrinsics::<T>(), pose::<T>()) else {
        return;
    };
    if let Ok(p) = FixedProjection::from_camera(&k, &pose) {
        let x3 = black_box([Q16::from_int(1), Q16::from_int(-2), Q16::from_bits(7)]);
        black_box(p.project(&x3).ok());
        black_box(p.transfer(&x3).ok());
    }
    black_box(Q16::from_float(black_box(lit::<T>(1.5))).ok());
}

// ---------------------------------------------------------------- pyramid

#[cfg(feature = "pyramid")]
fn run_pyramid() {
    use camgeom::pyramid::pyr_down;
    let frame = black_box([0u8; W * H]);
    let mut buf = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    if let Ok(p) = Pyramid::build(v, black_box(&mut buf[..]), black_box(4)) {
        black_box(p.level(black_box(2)));
    }
    if let Ok(p) = Pyramid::from_buffer(v, black_box(&buf[..]), black_box(3)) {
        black_box(p.level(black_box(1)));
    }
    let mut pair = camgeom::pyramid::PyramidPair::new(
        [black_box([0u8; W * H]), black_box([0u8; W * H])],
        [black_box([0u8; W * H / 2]), black_box([0u8; W * H / 2])],
    );
    if pair
        .set_geometry(black_box(W), black_box(H), black_box(3))
        .is_ok()
    {
        if let Ok(mut img) = pair.capture() {
            black_box(img.copy_from(&v).ok());
        }
        if let Ok(p) = pair.advance() {
            black_box(p.next.level(black_box(1)));
        }
        pair.rewind();
        black_box(pair.previous_mut().ok().flatten().is_some());
    }
    let mut small = black_box([0u8; W * H]);
    let (w, h) = black_box((W / 2, H / 2));
    if let Ok(mut dst) = ImageMut::packed(black_box(&mut small[..]), w, h) {
        black_box(pyr_down(&v, &mut dst).ok());
    }
}

// ---------------------------------------------------------------- gradient

#[cfg(feature = "gradient")]
fn run_gradient() {
    use camgeom::gradient::{scharr_level, scharr_row, scharr_window};
    let frame = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    let mut row = black_box([[0i16; 2]; W]);
    scharr_row(&v, black_box(3), black_box(1), black_box(&mut row[..]));
    let mut level = black_box([[0i16; 2]; W * H]);
    let (w, h) = black_box((W, H));
    if let Ok(mut dst) = ImageMut::packed(black_box(&mut level[..]), w, h) {
        black_box(scharr_level(&v, &mut dst).ok());
    }
    let mut win = black_box([[0i16; 2]; 21 * 21]);
    let (x0, y0, ww, wh) = black_box((-3isize, 5isize, 21usize, 21usize));
    black_box(scharr_window(&v, x0, y0, ww, wh, black_box(&mut win[..])).ok());
    black_box(&row);
}

// ---------------------------------------------------------------- corners

#[cfg(feature = "corners")]
fn run_corners() {
    use camgeom::corners::{Corner, CornerConfig, good_features};
    use camgeom::heapless::Vec;
    let frame = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    let mut candidates = black_box([Corner::default(); 64]);
    let mut scratch = black_box([0u32; 6 * W]);
    let existing = black_box([[3i32, 4]; 4]);
    let cfg = black_box(CornerConfig::default())
        .check()
        .unwrap_or_default();
    let mut out: Vec<Corner, 32> = Vec::new();
    black_box(
        good_features(
            &v,
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

// ---------------------------------------------------------------- klt

/// `calc_flow` (without and with bordered copies) and `forward_backward` with fixed-point and
/// `f32` arithmetic, every gradient mode, and the multi-frame tracker.
#[cfg(feature = "klt")]
fn run_klt() {
    use camgeom::corners::Corner;
    use camgeom::klt::{
        Borders, Fixed, Flow, FlowArith, Gradients, LkConfig, LkParams, Q16, Templates, Tracker,
        TrackerConfig, calc_flow, forward_backward,
    };
    fn flows<A: FlowArith>(pa: &Pyramid<'_>, pb: &Pyramid<'_>, cfg: &LkParams, pt: A::Coord)
    where
        A::Coord: Copy + Default,
        Flow<A::Coord>: Copy + Default,
    {
        let pts = black_box([[pt; 2]; 8]);
        let mut fw = black_box([Flow::<A::Coord>::default(); 8]);
        let mut bw = black_box([Flow::<A::Coord>::default(); 8]);
        let mut scratch = black_box([0i16; 4096]);
        let mut grad = black_box([[0i16; 2]; W * H]);
        black_box(
            calc_flow::<A>(
                pa,
                pb,
                &pts,
                &mut fw,
                cfg,
                Gradients::PerWindow,
                Borders::None,
                &mut scratch,
            )
            .ok(),
        );
        black_box(
            calc_flow::<A>(
                pa,
                pb,
                &pts,
                &mut fw,
                cfg,
                Gradients::PerLevel(black_box(&mut grad[..])),
                Borders::None,
                &mut scratch,
            )
            .ok(),
        );
        let mut borders = black_box([0u8; 8192]);
        black_box(
            calc_flow::<A>(
                pa,
                pb,
                &pts,
                &mut fw,
                cfg,
                Gradients::Auto(black_box(&mut grad[..])),
                Borders::Copy(black_box(&mut borders[..])),
                &mut scratch,
            )
            .ok(),
        );
        black_box(
            forward_backward::<A>(
                pa,
                pb,
                &pts,
                &mut fw,
                &mut bw,
                cfg,
                Gradients::PerWindow,
                &mut scratch,
            )
            .ok(),
        );
        black_box((&fw, &bw));
    }
    let a = black_box([0u8; W * H]);
    let b = black_box([0u8; W * H]);
    let mut pa_buf = black_box([0u8; W * H]);
    let mut pb_buf = black_box([0u8; W * H]);
    let (Some(va), Some(vb)) = (view(&a), view(&b)) else {
        return;
    };
    let levels = black_box(3usize);
    let (Ok(pa), Ok(pb)) = (
        Pyramid::build(va, black_box(&mut pa_buf[..]), levels),
        Pyramid::build(vb, black_box(&mut pb_buf[..]), levels),
    ) else {
        return;
    };
    let Ok(cfg) = black_box(LkConfig::default()).check() else {
        return;
    };
    flows::<Fixed>(&pa, &pb, &cfg, black_box(Q16::from_int(10)));
    flows::<f32>(&pa, &pb, &cfg, black_box(10.5));

    let Ok(tp) = black_box(TrackerConfig::default()).check() else {
        return;
    };
    let mut candidates = black_box([Corner::default(); 64]);
    let mut cscratch = black_box([0u32; 6 * W]);
    let mut fscratch = black_box([0i16; 4096]);
    let mut t = Tracker::<Fixed, 32>::new();
    black_box(t.replenish(&tp, &va, &mut candidates, &mut cscratch).ok());
    black_box(
        t.update(&tp, &pa, &pb, black_box(Templates::Compute), &mut fscratch)
            .ok(),
    );
    black_box(t.tracks());
    let mut t = Tracker::<f32, 32>::new();
    black_box(t.replenish(&tp, &va, &mut candidates, &mut cscratch).ok());
    black_box(
        t.update(&tp, &pa, &pb, black_box(Templates::Compute), &mut fscratch)
            .ok(),
    );
    black_box(t.tracks());
}

// ---------------------------------------------------------------- homography

#[cfg(feature = "homography")]
fn run_homography<T: Real>() {
    use camgeom::homography::{Homography, dlt, find_homography, refine};
    let src = points2::<T, N>();
    let dst = points2::<T, N>();
    let mut mask = black_box([false; N]);
    let cfg = ransac_params::<T>();
    black_box(find_homography(&src, &dst, &cfg, &mut mask).ok());
    let s4 = points2::<T, 4>();
    let d4 = points2::<T, 4>();
    if let Ok(h) = Homography::from_four_points(&s4, &d4) {
        black_box(h.transfer(&black_box(pt2(3.0, 4.0))).ok());
        black_box(h.inverse().ok());
    }
    if let Ok(h) = dlt(&src, &dst) {
        black_box(refine(&h, &src, &dst, black_box(10)).ok());
    }
}

// ---------------------------------------------------------------- pose

#[cfg(feature = "pose")]
fn run_pose<T: Real>() {
    use camgeom::pose::{
        PlanarConfig, epnp, ippe, p3p, refine_pose, solve_planar, solve_pnp, solve_pnp_ransac,
    };
    let Some(cam) = camera::<T>() else { return };
    let model = points2::<T, N>();
    let pixels = points2::<T, N>();
    let world = points3::<T, N>();
    let mut scratch = points2::<T, N>();
    let mut mask = black_box([false; N]);
    let cfg = black_box(PlanarConfig::default());
    black_box(solve_planar(&cam, &model, &pixels, &mut scratch, &cfg).ok());
    black_box(ippe(&model, &pixels).ok());
    black_box(epnp(&world, &pixels).ok());
    let bearings = black_box([Vector3::new(lit::<T>(0.1), lit(0.2), lit(1.0)); 3]);
    black_box(p3p(&bearings, &points3::<T, 3>()).ok());
    black_box(solve_pnp(&cam, &world, &pixels, &mut scratch).ok());
    let rc = ransac_params::<T>();
    black_box(solve_pnp_ransac(&cam, &world, &pixels, &mut scratch, &rc, &mut mask).ok());
    if let Some(p) = pose::<T>() {
        black_box(refine_pose(&cam, &p, &world, &pixels, black_box(10)).ok());
    }
}

// ---------------------------------------------------------------- target

/// Two frames (acquisition, then tracking) of the planar target, acquired from given corners
/// and from an AprilTag.
#[cfg(feature = "target")]
fn run_target() {
    use camgeom::apriltag::{Detector, DetectorConfig, TagTarget, families};
    use camgeom::klt::Fixed;
    use camgeom::target::{
        Acquire, GivenCorners, PlanarTarget, TargetConfig, TargetParams, corner_scratch_len,
        flow_scratch_len,
    };
    fn two_frames<Q: Acquire>(params: &TargetParams, acquire: &mut Q) {
        two_pyramids(|pa, pb| step_twice(params, acquire, pa, pb));
    }
    fn step_twice<Q: Acquire>(
        params: &TargetParams,
        acquire: &mut Q,
        pa: &Pyramid<'_>,
        pb: &Pyramid<'_>,
    ) {
        let mut target = black_box(PlanarTarget::<
            Fixed,
            32,
            { flow_scratch_len(15) },
            { corner_scratch_len(W) },
            64,
        >::new());
        black_box(target.step(params, None, pa, acquire, &mut ()).ok());
        black_box(target.step(params, Some(pa), pb, acquire, &mut ()).ok());
    }
    let Some(cam) = camera::<f32>() else { return };
    let cfg = black_box(TargetConfig::default());
    let size = black_box([0.2f32, 0.15f32]);
    let Ok(params) = TargetParams::new(&cfg, cam, size) else {
        return;
    };
    let mut given = GivenCorners::new(black_box([
        Point2::new(10.0f32, 10.0),
        Point2::new(50.0, 10.0),
        Point2::new(50.0, 40.0),
        Point2::new(10.0, 40.0),
    ]));
    two_frames(&params, &mut given);
    let Ok(detector) = Detector::new(
        black_box(DetectorConfig::default()),
        &[black_box(&families::TAG36H11)],
    ) else {
        return;
    };
    let mut ws = black_box(SmallWorkspace::new());
    let mut tag = TagTarget::new(
        &detector,
        ws.as_mut_view(),
        &families::TAG36H11,
        black_box(3),
    );
    two_frames(&params, &mut tag);
}

/// An AprilTag workspace for `W`x`H` frames.
#[cfg(any(feature = "target", feature = "apriltag"))]
type SmallWorkspace = camgeom::apriltag::Workspace<
    W,
    { camgeom::apriltag::tiles_len(W, H, 1) },
    1024,
    64,
    2048,
    { camgeom::apriltag::sort_len(W, H, 1) },
>;

// ---------------------------------------------------------------- draw

#[cfg(feature = "draw")]
fn run_draw<T: Real>() {
    use camgeom::draw::{WireframeConfig, cube, draw_line, draw_line_i32, draw_wireframe};
    let Some(cam) = camera::<T>() else { return };
    let Some(pose) = pose::<T>() else { return };
    let mut frame = black_box([0u8; W * H]);
    let Some(mut img) = image_mut(&mut frame) else {
        return;
    };
    let (vertices, edges) = black_box(cube(lit::<T>(0.05), lit(0.025), lit(0.1)));
    let Ok(params) = black_box(WireframeConfig::<T>::default()).check() else {
        return;
    };
    black_box(draw_wireframe(&mut img, &cam, &pose, &vertices, &edges, &params).ok());
    let (a, b) = black_box((pt2::<T>(-5.0, 3.0), pt2::<T>(80.0, 30.0)));
    black_box(draw_line(&mut img, &a, &b, black_box(255)).ok());
    let [x0, y0, x1, y1] = black_box([-100i32, 5, 1000, 40]);
    black_box(draw_line_i32(&mut img, x0, y0, x1, y1, black_box(7)));
}

// ---------------------------------------------------------------- features

/// FAST, ORB (OpenCV's settings, and with a grid and sub-pixel positions into a slice) and
/// brute-force Hamming matching.
#[cfg(feature = "features")]
fn run_features() {
    use camgeom::features::{
        Descriptor, FastConfig, Feature, Match, MatchConfig, OrbConfig, fast_detect,
        match_descriptors, match_descriptors_guided, orb_detect, orb_detect_into,
    };
    use camgeom::heapless::Vec;
    let frame = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    let Ok(fparams) = black_box(FastConfig::default()).check() else {
        return;
    };
    let mut scratch = black_box([0u8; 16 * 1024]);
    let mut n = 0u32;
    black_box(
        fast_detect(&v, &fparams, black_box(&mut scratch[..]), |c| {
            n = n.wrapping_add(u32::from(c.x));
        })
        .ok(),
    );
    black_box(n);
    let Ok(oparams) = black_box(OrbConfig::default()).check() else {
        return;
    };
    let mut out: Vec<Feature, 32> = Vec::new();
    black_box(orb_detect(&v, &oparams, black_box(&mut scratch[..]), &mut out).ok());
    black_box(&out);
    // The spread and sub-pixel options, into a slice.
    let grid = OrbConfig {
        grid_cell: 16,
        cell_keep: 2,
        subpixel: true,
        ..OrbConfig::default()
    };
    let Ok(gparams) = black_box(grid).check() else {
        return;
    };
    let mut slots = black_box([Feature::default(); 48]);
    black_box(orb_detect_into(&v, &gparams, black_box(&mut scratch[..]), &mut slots[..]).ok());
    black_box(&slots);
    let q = black_box([Descriptor([1; 8]); 8]);
    let t = black_box([Descriptor([2; 8]); 12]);
    let Ok(mparams) = black_box(MatchConfig::default()).check() else {
        return;
    };
    let mut ms = black_box([0u32; 64]);
    let mut matches = black_box([Match::default(); 8]);
    black_box(match_descriptors(&q, &t, &mparams, &mut ms, &mut matches).ok());
    black_box(&matches);
    // Guided: a predicate the optimiser cannot see through.
    let band = black_box(3usize);
    let admit = |i: usize, j: usize| i.abs_diff(j) <= band;
    black_box(match_descriptors_guided(&q, &t, &mparams, admit, &mut ms, &mut matches).ok());
    black_box(&matches);
    // SIFT, both image sizes (as given and doubled), and float matching.
    use camgeom::features::matching::{FloatDescriptor, FloatMatch, match_float_descriptors};
    use camgeom::features::sift::{self, SiftConfig, SiftFeature, sift_detect};
    let mut fscratch = black_box([0.0f32; sift::scratch_len(W, H, 3, true)]);
    let mut sifts = black_box([SiftFeature::default(); 8]);
    let upsample = black_box(true);
    let Ok(sparams) = black_box(SiftConfig {
        upsample,
        root: black_box(false),
        ..SiftConfig::default()
    })
    .check() else {
        return;
    };
    black_box(sift_detect(&v, &sparams, &mut fscratch[..], &mut sifts[..]).ok());
    black_box(&sifts);
    let fq = black_box([FloatDescriptor::default(); 4]);
    let ft = black_box([FloatDescriptor([0.5; 128]); 6]);
    let mut fm = black_box([FloatMatch::default(); 4]);
    black_box(match_float_descriptors(&fq, &ft, &mparams, &mut ms, &mut fm).ok());
    black_box(&fm);
}

// ---------------------------------------------------------------- warp

/// Perspective warps, float and integer per-pixel arithmetic.
#[cfg(feature = "warp")]
fn run_warp() {
    use camgeom::arith::{Arithmetic, Fixed};
    use camgeom::homography::Homography;
    use camgeom::warp::{WarpConfig, warp_into_quad, warp_perspective_into};
    let logo = black_box([0u8; 16 * 16]);
    let (lw, lh) = black_box((16usize, 16usize));
    let Ok(src) = ImageView::packed(black_box(&logo[..]), lw, lh) else {
        return;
    };
    let mut frame = black_box([0u8; W * H]);
    let Some(mut dst) = image_mut(&mut frame) else {
        return;
    };
    let quad = points2::<f32, 4>();
    fn both<A: Arithmetic>(
        src: &ImageView<'_, u8>,
        dst: &mut camgeom::image::ImageMut<'_, u8>,
        quad: &[camgeom::nalgebra::Point2<f32>; 4],
    ) {
        let cfg = black_box(WarpConfig { alpha: 200 });
        black_box(warp_into_quad::<A>(src, dst, quad, &cfg).ok());
        let m = black_box(camgeom::nalgebra::Matrix3::from_element(0.5f32));
        if let Ok(h) = Homography::from_matrix(&m) {
            black_box(warp_perspective_into::<A>(src, dst, &h, &cfg).ok());
        }
    }
    both::<f32>(&src, &mut dst, &quad);
    both::<Fixed>(&src, &mut dst, &quad);
}

// ---------------------------------------------------------------- twoview

#[cfg(feature = "twoview")]
fn run_twoview<T: Real>() {
    use camgeom::transform::Transform;
    use camgeom::twoview::{
        View1, eight_point, find_essential, find_fundamental, five_point, recover_pose,
        refine_essential, refine_fundamental, seven_point, triangulate_dlt, triangulate_midpoint,
        triangulate_optimal,
    };
    let x1 = points2::<T, N>();
    let x2 = points2::<T, N>();
    let mut mask = black_box([false; N]);
    let cfg = ransac_params::<T>();
    black_box(eight_point(&x1, &x2).ok());
    black_box(seven_point(&points2::<T, 7>(), &points2::<T, 7>()).ok());
    black_box(five_point(&points2::<T, 5>(), &points2::<T, 5>()).ok());
    if let Ok((f, _)) = find_fundamental(&x1, &x2, &cfg, &mut mask) {
        black_box(refine_fundamental(&f, &x1, &x2, Some(&mask[..]), black_box(10)).ok());
    }
    let Some(k) = intrinsics::<T>() else { return };
    if let Ok((e, _)) = find_essential(&k, &k, &x1, &x2, &cfg, &mut mask) {
        black_box(refine_essential(&e, &k, &k, &x1, &x2, None, black_box(10)).ok());
        let max_distance = black_box(lit::<T>(50.0));
        if let Ok(r) = recover_pose(&e, &k, &k, &x1, &x2, max_distance, &mut mask) {
            let p1 = Transform::<View1, View1, T>::identity();
            let (a, b) = black_box((pt2::<T>(0.1, 0.2), pt2::<T>(0.15, 0.2)));
            black_box(triangulate_dlt(&p1, &r.pose, &a, &b).ok());
            black_box(triangulate_midpoint(&p1, &r.pose, &a, &b).ok());
            black_box(triangulate_optimal(&p1, &r.pose, &a, &b).ok());
        }
    }
}

// ---------------------------------------------------------------- sfm

/// Three-view reconstruction (with its bundle adjustment) and a bundle adjustment alone.
#[cfg(feature = "sfm")]
fn run_sfm<T: Real>() {
    use camgeom::sfm::{
        PointBlock, SfmConfig, SfmWorkspace, Track, bundle_adjust, reconstruct_three_views,
    };
    let Some(cam) = camera::<T>() else { return };
    let tracks: [Track<T>; N] = black_box([[Some(pt2(1.0, 2.0)); 3]; N]);
    let Ok(cfg) = black_box(SfmConfig::default()).check() else {
        return;
    };
    let mut ws = black_box(SfmWorkspace::<T, N>::new());
    black_box(reconstruct_three_views(&cam, &tracks, &cfg, &mut ws).ok());
    let Some(p) = pose::<T>() else { return };
    let mut poses = black_box([p; 3]);
    let mut points = black_box([Some(pt3::<T>(0.1, 0.2, 1.0)); N]);
    let used = black_box([[true; 3]; N]);
    let mut blocks = black_box([PointBlock::<T>::default(); N]);
    black_box(
        bundle_adjust(
            &cam,
            &mut poses,
            &mut points,
            &tracks,
            &used,
            &mut blocks,
            black_box(5),
        )
        .ok(),
    );
    run_sfm_incremental::<T>(&cam);
}

/// The incremental reconstruction over any number of views: tracks built by union-find, checked
/// into a `TrackSet`, reconstructed (with its bundle adjustments).
#[cfg(feature = "sfm")]
fn run_sfm_incremental<T: Real>(cam: &camgeom::camera::Camera<T>) {
    use camgeom::sfm::{
        BundleScratch, IncrementalConfig, Observation, PointScratch, Scene, TrackBuilder, TrackSet,
        ViewResult, Workspace, reconstruct,
    };
    use camgeom::transform::Pose;
    const V: usize = 3;
    const O: usize = 2 * N;
    let (mut parent, mut scratch, mut labels) = black_box(([0u32; O], [0u32; O], [0u32; O]));
    if let Ok(mut b) = TrackBuilder::new(&mut parent, &mut scratch) {
        for i in 0..black_box(N as u32) {
            black_box(b.join(i, i + N as u32).ok());
        }
        black_box(
            b.label(&black_box([0, N as u32, O as u32]), &mut labels)
                .ok(),
        );
    }
    let starts: [u32; N + 1] = black_box(core::array::from_fn(|i| 2 * i as u32));
    let obs: [Observation<T>; O] = black_box(core::array::from_fn(|k| Observation {
        view: (k % 2) as u16,
        pixel: pt2(1.0, 2.0),
    }));
    let Ok(set) = TrackSet::new_checked(&starts, &obs, V) else {
        return;
    };
    let Ok(params) = black_box(IncrementalConfig::<T>::default()).check() else {
        return;
    };
    let mut poses: [Option<Pose<T>>; V] = black_box([None; V]);
    let mut views = black_box([ViewResult::<T>::default(); V]);
    let mut points = black_box([None; N]);
    let mut used = black_box([false; O]);
    let mut normalized = black_box([None; O]);
    let mut covisibility = black_box([0u32; V * V]);
    let mut tried = black_box([0u32; V]);
    let mut counts = black_box([0u32; V]);
    let mut free = black_box([true; V]);
    let (mut first, mut second) = black_box(([pt2::<T>(0.0, 0.0); N], [pt2::<T>(0.0, 0.0); N]));
    let mut world = black_box([pt3::<T>(0.0, 0.0, 1.0); N]);
    let mut index = black_box([0u32; N]);
    let (mut mask, mut mask2) = black_box(([false; N], [false; N]));
    let mut angles = black_box([T::zero(); N]);
    let mut system = black_box([T::zero(); 36 * V * V]);
    let (mut rhs, mut gradient) = black_box(([T::zero(); 6 * V], [T::zero(); 6 * V]));
    let mut bindex = black_box([0u16; V]);
    let mut trial: [Option<Pose<T>>; V] = black_box([None; V]);
    let mut coupling = black_box([camgeom::nalgebra::SMatrix::<T, 6, 3>::zeros(); O]);
    let mut pscratch = black_box([PointScratch::<T>::default(); N]);
    let mut scene = Scene {
        poses: &mut poses,
        views: &mut views,
        points: &mut points,
        used: &mut used,
    };
    let mut ws = Workspace {
        normalized: &mut normalized,
        covisibility: &mut covisibility,
        tried: &mut tried,
        counts: &mut counts,
        first: &mut first,
        second: &mut second,
        world: &mut world,
        index: &mut index,
        mask: &mut mask,
        mask2: &mut mask2,
        angles: &mut angles,
        bundle: BundleScratch {
            system: &mut system,
            rhs: &mut rhs,
            gradient: &mut gradient,
            index: &mut bindex,
            free: &mut free,
            trial: &mut trial,
            coupling: &mut coupling,
            points: &mut pscratch,
        },
    };
    black_box(reconstruct(cam, &set, &params, &mut scene, &mut ws).ok());
}

// ---------------------------------------------------------------- calib

/// Calibration from views of a 4x3 board, Brown-Conrady and fisheye.
#[cfg(feature = "calib")]
fn run_calib<T: Real>() {
    use camgeom::calib::{CalibrationConfig, Calibrator};
    use camgeom::camera::LensModel;
    use camgeom::chessboard::BoardSize;
    let Ok(board) = BoardSize::new(black_box(4), black_box(3)) else {
        return;
    };
    let Ok(mut c) = Calibrator::<T, 4, 12>::new(board, black_box(lit(0.025)), W, H) else {
        return;
    };
    let corners = points2::<T, 12>();
    for _ in 0..black_box(4) {
        black_box(c.add_view(W, H, &corners).ok());
    }
    for model in [LensModel::BrownConrady, LensModel::KannalaBrandt] {
        let Ok(cfg) = black_box(CalibrationConfig {
            model,
            ..CalibrationConfig::default()
        })
        .check() else {
            continue;
        };
        black_box(c.solve(&cfg).ok());
        if let Some(guess) = camera::<T>() {
            black_box(c.solve_with_guess(&cfg, &guess).ok());
        }
    }
    // A board of identified points seen in part (ChArUco, AprilGrid).
    let plane: [Point2<T>; 12] = core::array::from_fn(|k| {
        Point2::new(lit((k % 4) as f64 * 0.025), lit((k / 4) as f64 * 0.025))
    });
    let Ok(mut c) = Calibrator::<T, 4, 12>::with_points(&plane, lit(0.025), W, H) else {
        return;
    };
    let ids: [usize; 12] = core::array::from_fn(|k| black_box(k));
    for v in 0..black_box(4) {
        let n = 12 - v;
        if let (Some(i), Some(p)) = (ids.get(v..), corners.get(..n)) {
            black_box(c.add_points(W, H, i, p).ok());
        }
    }
    if let Ok(cfg) = black_box(CalibrationConfig::default()).check() {
        black_box(c.solve(&cfg).ok());
    }
}

// ---------------------------------------------------------------- chessboard

/// Detection with each refinement, and both refinements alone.
#[cfg(feature = "chessboard")]
fn run_chessboard() {
    use camgeom::chessboard::{
        BoardSize, ChessboardDetector, DetectConfig, Refinement, SaddleConfig, SubPixConfig,
        corner_subpix, pyramid_len, saddle_subpix, scratch_len,
    };
    let frame = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    let Ok(board) = BoardSize::new(black_box(4), black_box(3)) else {
        return;
    };
    let mut det = black_box(ChessboardDetector::<128>::new());
    let mut scratch = black_box([0i32; scratch_len(W)]);
    for refine in [
        Refinement::None,
        Refinement::CornerSubPix(SubPixConfig::default()),
        Refinement::AdaptiveCornerSubPix(SubPixConfig::default()),
        Refinement::Saddle(SaddleConfig::default()),
    ] {
        let Ok(params) = black_box(DetectConfig {
            refine,
            ..DetectConfig::default()
        })
        .check() else {
            continue;
        };
        black_box(det.detect::<12>(&v, board, &params, &mut scratch).ok());
        let mut pyramid = black_box([0u8; pyramid_len(W, H)]);
        black_box(
            det.detect_any_scale::<12>(&v, board, &params, &mut pyramid, &mut scratch)
                .ok(),
        );
    }
    let mut corners = points2::<f32, 12>();
    if let Ok(sp) = black_box(SubPixConfig::default()).check() {
        black_box(corner_subpix(&v, &mut corners, &sp).ok());
    }
    if let Ok(sc) = black_box(SaddleConfig::default()).check() {
        black_box(saddle_subpix(&v, &mut corners, &sc).ok());
    }
    black_box(&corners);
}

// ---------------------------------------------------------------- apriltag

/// Detection, decoding and the tag's pose.
#[cfg(feature = "apriltag")]
fn run_apriltag() {
    use camgeom::apriltag::{Detection, Detector, DetectorConfig, families, tag_pose};
    use camgeom::pose::PlanarConfig;
    let frame = black_box([0u8; W * H]);
    let Some(v) = view(&frame) else { return };
    let Ok(detector) = Detector::new(black_box(DetectorConfig::default()), &families::ALL) else {
        return;
    };
    let mut ws = black_box(SmallWorkspace::new());
    let Ok(found) = detector.detect::<4>(&v, &mut ws.as_mut_view()) else {
        return;
    };
    let Some(cam) = camera::<f32>() else { return };
    let cfg = black_box(PlanarConfig::default());
    for d in &found {
        black_box(tag_pose(d, black_box(0.05), &cam, &cfg).ok());
    }
    black_box(
        detector
            .find_target(&v, &mut ws.as_mut_view(), &families::TAG25H9, black_box(2))
            .ok(),
    );
    // Tracking by detection: the refinement and the region search from an opaque prediction.
    let predicted = black_box([Point2::new(black_box(3.5f32), black_box(-2.0)); 4]);
    black_box(detector.refine_target(&v, &families::TAG36H11, black_box(7), &predicted));
    black_box(detector.refine_detection(&v, &families::TAG36H11, black_box(7), &predicted));
    run_apriltag_partial(&detector, &v, &predicted);
    black_box(
        detector
            .find_target_near(
                &v,
                &mut ws.as_mut_view(),
                &families::TAG36H11,
                black_box(7),
                &predicted,
            )
            .ok(),
    );
    for f in families::ALL {
        black_box(f.decode(black_box(0x1234_5678_9abc), black_box(2)));
    }
    run_apriltag_wide_labels(&detector, &v);
    run_aruco(&v, &mut ws);
    run_board(&found, &cam);
    run_charuco(&v, &mut ws);
    run_aprilgrid(&v, &mut ws);
}

/// AprilGrid: the layout, a view's corners detected (none on this frame) and from opaque
/// detections, the 2-cell-border family's decoder.
#[cfg(feature = "apriltag")]
fn run_aprilgrid(v: &ImageView<'_, u8>, ws: &mut SmallWorkspace) {
    use camgeom::aprilgrid::{AprilGrid, GridCorner, grid_corners, refine_corners};
    use camgeom::apriltag::{Detection, Detector};
    use camgeom::homography::Homography;
    let Ok(grid) = AprilGrid::new(black_box(3), black_box(2), black_box(0.03), black_box(0.3))
    else {
        return;
    };
    black_box(grid.point(black_box(7)));
    black_box(grid.tag_points(black_box(4)));
    let Ok(detector) = Detector::new(black_box(AprilGrid::detector_config()), &[grid.family()])
    else {
        return;
    };
    let mut tags = camgeom::heapless::Vec::<Detection, 6>::new();
    let mut out = [GridCorner::default(); 24];
    let saddle = camgeom::chessboard::SaddleConfig::default().check().ok();
    black_box(
        grid.detect_corners(
            &detector,
            v,
            &mut ws.as_mut_view(),
            &mut tags,
            saddle.as_ref(),
            &mut out,
        )
        .ok(),
    );
    let h = Homography::<f32>::identity();
    let fake = |id: u16| Detection {
        family: grid.family(),
        id: black_box(id),
        hamming: 0,
        decision_margin: 50.0,
        corners: black_box([Point2::new(black_box(1.0f32), 2.0); 4]),
        center: Point2::new(3.0, 4.0),
        homography: h,
    };
    black_box(grid_corners(&grid, &[fake(1), fake(1), fake(4)], &mut out).ok());
    if let Some(s) = saddle.as_ref() {
        black_box(refine_corners(v, &mut out, black_box(24), s).ok());
    }
    black_box(
        grid.family()
            .decode(black_box(0x1234_5678_9abc), black_box(2)),
    );
}

/// A tag board: the const grid table, a grid laid out at run time, a listed board checked,
/// and the board pose from the frame's detections and from opaque ones.
#[cfg(feature = "apriltag")]
fn run_board(found: &[camgeom::apriltag::Detection], cam: &camgeom::camera::Camera<f32>) {
    use camgeom::apriltag::{
        BoardBuffers, BoardConfig, BoardTag, GridBoard, TagBoard, board_pose, families, grid_tags,
    };
    const TAGS: [BoardTag; 6] = grid_tags(3, 0.04, 0.01, 0);
    let tags = black_box(TAGS);
    let mut buf = black_box(BoardBuffers::<f32, 24>::new());
    let cfg = black_box(BoardConfig::default());
    if let Ok(board) = TagBoard::new(&families::DICT_4X4_50, &tags) {
        black_box(board_pose(&board, found, cam, &cfg, &mut buf).ok());
    }
    let grid = GridBoard {
        markers_x: black_box(2),
        markers_y: black_box(2),
        marker_length: black_box(0.05f32),
        marker_separation: black_box(0.01),
        first_id: black_box(3),
    };
    let mut out = black_box(
        [BoardTag {
            id: 0,
            corners: [[0.0f32; 3]; 4],
        }; 4],
    );
    if let Ok(board) = grid.fill(&families::TAG36H11, &mut out) {
        black_box(board_pose(&board, found, cam, &cfg, &mut buf).ok());
    }
    black_box(grid.tag(black_box(9)));
}

/// ChArUco: the board layout and the corner interpolation from the markers detected (none on
/// this frame) and from opaque detections of two adjacent markers.
#[cfg(feature = "apriltag")]
fn run_charuco(v: &ImageView<'_, u8>, ws: &mut SmallWorkspace) {
    use camgeom::apriltag::{Detection, Detector, DetectorConfig, families};
    use camgeom::charuco::{CharucoBoard, CharucoConfig, CharucoCorner, interpolate_corners};
    use camgeom::homography::Homography;
    let Ok(board) = CharucoBoard::new(
        black_box(5),
        black_box(4),
        black_box(0.04),
        black_box(0.03),
        &families::DICT_4X4_50,
    ) else {
        return;
    };
    let Ok(detector) = Detector::new(black_box(DetectorConfig::default()), &[board.dictionary()])
    else {
        return;
    };
    let Ok(params) = black_box(CharucoConfig::default()).check() else {
        return;
    };
    let mut out = [CharucoCorner::default(); 12];
    if let Ok(found) = detector.detect::<8>(v, &mut ws.as_mut_view()) {
        black_box(interpolate_corners(&board, v, &found, &params, &mut out).ok());
    }
    let fake = |id: u16, x: f32| Detection {
        family: &families::DICT_4X4_50,
        id: black_box(id),
        hamming: 0,
        decision_margin: 50.0,
        corners: black_box([
            Point2::new(x, 30.0),
            Point2::new(x + 20.0, 30.0),
            Point2::new(x + 20.0, 10.0),
            Point2::new(x, 10.0),
        ]),
        center: Point2::new(x + 10.0, 20.0),
        homography: Homography::identity(),
    };
    let dets = [fake(0, 10.0), fake(2, 40.0)];
    black_box(interpolate_corners(&board, v, &dets, &params, &mut out).ok());
}

/// ArUco: OpenCV's dictionaries through the same detector (every group's table, mixed with an
/// AprilTag family, OpenCV's largest correction rate), OpenCV's corner order and the bound of
/// each detection, the tracking refinement of a marker, each dictionary's decoder and the
/// look-up by name.
#[cfg(feature = "apriltag")]
fn run_aruco(v: &ImageView<'_, u8>, ws: &mut SmallWorkspace) {
    use camgeom::apriltag::{Detector, DetectorConfig, families};
    let cfg = DetectorConfig {
        error_correction_rate: black_box(1.0),
        ..black_box(DetectorConfig::default())
    };
    let sets: [[&'static camgeom::apriltag::Family; 4]; 2] = [
        [
            &families::DICT_4X4_50,
            &families::DICT_5X5_1000,
            &families::DICT_6X6_250,
            &families::DICT_7X7_1000,
        ],
        [
            &families::DICT_ARUCO_ORIGINAL,
            &families::DICT_ARUCO_MIP_36H12,
            &families::TAG36H11,
            &families::DICT_4X4_1000,
        ],
    ];
    let predicted = black_box([Point2::new(black_box(3.5f32), black_box(-2.0)); 4]);
    for set in sets {
        let Ok(det) = Detector::new(cfg, black_box(&set)) else {
            continue;
        };
        if let Ok(found) = det.detect::<4>(v, &mut ws.as_mut_view()) {
            for d in &found {
                black_box(d.aruco_corners());
                black_box(det.max_hamming_for(d.family));
            }
        }
        black_box(det.refine_detection(v, set[0], black_box(7), &predicted));
    }
    for f in families::ARUCO {
        black_box(f.decode(black_box(0x1234_5678_9abc), black_box(9)));
    }
    black_box(families::by_name(black_box("DICT_6X6_250")));
}

/// A partly seen tag from an opaque prediction: the robust edge fit, the seen cells' reading
/// and their confirmation (`Detector::refine_partial`).
#[cfg(feature = "apriltag")]
#[inline(never)]
fn run_apriltag_partial(
    detector: &camgeom::apriltag::Detector,
    v: &ImageView<'_, u8>,
    predicted: &[Point2<f32>; 4],
) {
    use camgeom::apriltag::families;
    black_box(
        detector
            .refine_partial(v, &families::TAG36H11, black_box(7), predicted)
            .ok(),
    );
    black_box(
        detector
            .refine_partial(v, black_box(&families::TAG25H9), black_box(3), predicted)
            .ok(),
    );
}

/// The same detection through a [`camgeom::apriltag::WorkspaceView`] of `u32` labels (a
/// host's, sized at run time; here of stack buffers of opaque lengths).
#[cfg(feature = "apriltag")]
fn run_apriltag_wide_labels(detector: &camgeom::apriltag::Detector, v: &ImageView<'_, u8>) {
    use camgeom::apriltag::quad::Cluster;
    use camgeom::apriltag::segment::Run;
    use camgeom::apriltag::{Stats, WorkspaceView, sort_len, tiles_len};
    let mut tiles = [0u8; tiles_len(W, H, 1)];
    let (mut rmin, mut rmax) = ([0u8; W], [0u8; W]);
    let (mut r0, mut r1) = ([Run::<u32>::empty(); W], [Run::<u32>::empty(); W]);
    let (mut parent, mut size) = ([0u32; 1024], [0u8; 1024]);
    let mut slots = [Cluster::<u64>::empty(); 64];
    let mut pts = [0u32; 2048];
    let mut keys = [0u16; sort_len(W, H, 1)];
    let mut stats = Stats::default();
    let n = black_box(usize::MAX);
    let mut ws = WorkspaceView::with_labels(
        tiles
            .get_mut(..n.min(tiles_len(W, H, 1)))
            .unwrap_or(&mut []),
        &mut rmin,
        &mut rmax,
        [&mut r0, &mut r1],
        parent.get_mut(..n.min(1024)).unwrap_or(&mut []),
        &mut size,
        &mut slots,
        &mut pts,
        &mut keys,
        &mut stats,
    );
    black_box(detector.detect::<4>(v, &mut ws).ok());
    black_box(
        detector
            .find_target(
                v,
                &mut ws,
                &camgeom::apriltag::families::TAG25H9,
                black_box(2),
            )
            .ok(),
    );
}

// ---------------------------------------------------------------- remap

/// New camera matrix, both map kinds and both remaps, for both lens models.
#[cfg(feature = "remap")]
fn run_remap<T: Real>() {
    use camgeom::remap::{
        GridMap, MapEntry, WideEntry, build_map, grid_len, map_len, new_camera_matrix, remap,
    };
    let frame = black_box([0u8; W * H]);
    let Some(src) = view(&frame) else { return };
    let mut out = black_box([0u8; W * H]);
    let Some(mut dst) = image_mut(&mut out) else {
        return;
    };
    let (w, h) = black_box((W, H));
    for cam in [camera::<T>(), fisheye::<T>()].into_iter().flatten() {
        let Ok(k) = new_camera_matrix(&cam, w, h, black_box(lit(0.5))) else {
            continue;
        };
        let mut map = black_box([[0i16; 2]; map_len(W, H)]);
        if build_map(&cam, &k, w, h, &mut map).is_ok() {
            black_box(remap(&src, &map, &mut dst, black_box(0)).ok());
        }
        let mut wide = black_box([WideEntry::INVALID; map_len(W, H)]);
        if build_map(&cam, &k, w, h, &mut wide).is_ok() {
            black_box(remap(&src, &wide, &mut dst, black_box(0)).ok());
            let rgb = black_box([[0u8; 3]; W * H]);
            let mut out3 = black_box([[0u8; 3]; W * H]);
            if let (Ok(s3), Ok(mut d3)) = (
                ImageView::packed(&rgb[..], w, h),
                ImageMut::packed(&mut out3[..], w, h),
            ) {
                black_box(remap(&s3, &wide, &mut d3, black_box(0)).ok());
            }
        }
        let mut nodes = black_box([[0i32; 2]; grid_len(W, H, 3)]);
        if let Ok(g) = GridMap::build(&cam, &k, w, h, black_box(3), &mut nodes) {
            black_box(g.remap(&src, &mut dst, black_box(0)).ok());
        }
    }
}

// ---------------------------------------------------------------- vanishing

/// Vanishing points of opaque segments (buffers of opaque lengths), the grouped fit and the
/// horizon with and without intrinsics.
#[cfg(feature = "vanishing")]
fn run_vanishing<T: Real>() {
    use camgeom::vanishing::{
        MAX_POINTS, Segment, VanishingConfig, VanishingPoint, find_vanishing_points,
        fit_vanishing_point, horizon,
    };
    let ends = points2::<T, N>();
    let mut segments = [Segment::new(pt2(0.0, 0.0), pt2(1.0, 0.0)); N / 2];
    for (s, pair) in segments.iter_mut().zip(ends.chunks_exact(2)) {
        if let [a, b] = pair {
            *s = Segment::new(*a, *b);
        }
    }
    let segments = black_box(segments);
    let Ok(params) = black_box(VanishingConfig::<T>::default()).check() else {
        return;
    };
    let mut labels = [0u8; N / 2];
    let mut index = [0u32; N / 2];
    let mut mask = [false; N / 2];
    let mut out = [VanishingPoint::<T>::default(); MAX_POINTS];
    let found = find_vanishing_points(
        black_box(&segments[..]),
        &params,
        black_box(&mut labels[..]),
        black_box(&mut index[..]),
        black_box(&mut mask[..]),
        black_box(&mut out[..]),
    );
    if let Ok(count) = found {
        let points = out.get(..count).unwrap_or(&[]);
        black_box(horizon(points, None).ok());
        black_box(horizon(points, intrinsics::<T>().as_ref()).ok());
    }
    black_box(fit_vanishing_point(black_box(&segments[..]), |i| i % 2 == 0).ok());
}

// ---------------------------------------------------------------- resize

#[cfg(feature = "resize")]
fn run_resize() {
    use camgeom::resize::resize_bilinear;
    let frame = black_box([0u8; W * H]);
    let Some(src) = view(&frame) else { return };
    let mut out = black_box([0u8; 40 * 30]);
    let (w, h) = black_box((40usize, 30usize));
    if let Ok(mut dst) = ImageMut::packed(black_box(&mut out[..]), w, h) {
        black_box(resize_bilinear(&src, &mut dst).ok());
    }
}

// ---------------------------------------------------------------- link

/// The board application's record stream: a frame written, then bytes of unknown content and
/// length through the receiver (what a board reads from its link); a frame of unknown size cut
/// into pixel chunks, and a chunk of unknown content decoded.
#[cfg(feature = "link")]
fn run_link() {
    use camgeom_fw_app::link::{Deframer, encode_frame, max_frame_len};
    let record = black_box([0u8; 152]);
    let mut out = black_box([0u8; max_frame_len(152)]);
    let n = black_box(usize::MAX).min(out.len());
    black_box(encode_frame(black_box(7), &record, out.get_mut(..n).unwrap_or(&mut [])).ok());
    let bytes = black_box([0u8; 512]);
    let len = black_box(usize::MAX).min(bytes.len());
    let mut input = bytes.get(..len).unwrap_or(&[]);
    let mut rx = black_box(Deframer::<{ max_frame_len(152) }>::new());
    while let Some(f) = rx.push(&mut input) {
        black_box((f.seq, f.record.len()));
    }
    black_box(rx.stats());
    // A frame of unknown size and stride cut into chunk records, and a chunk of unknown
    // content read back.
    use camgeom_fw_app::frame_chunk::{CHUNK_LEN, FrameChunk, send_frame};
    let pixels = black_box([0u8; 1024]);
    let (w, h, stride) = black_box((usize::MAX, usize::MAX, usize::MAX));
    if let Ok(img) = camgeom::image::ImageView::new(&pixels, w, h, stride) {
        black_box(send_frame(black_box(3), &img, |c| {
            black_box(c);
        }))
        .ok();
    }
    black_box(FrameChunk::decode(&black_box([0u8; CHUNK_LEN])).ok());
}

// ---------------------------------------------------------------- command

/// Commands to the board and its stored settings: command records of unknown content decoded
/// and applied, the settings encoded, and a stored sector of unknown content decoded.
#[cfg(feature = "command")]
fn run_command() {
    use camgeom_fw_app::command::{Ack, COMMAND_LEN, Command};
    use camgeom_fw_app::settings::{SETTINGS_LEN, Settings};
    let bytes = black_box([0u8; COMMAND_LEN]);
    let len = black_box(usize::MAX).min(bytes.len());
    let Ok(mut settings) = Settings::decode(&black_box([0u8; SETTINGS_LEN])) else {
        return;
    };
    if let Ok(c) = Command::decode(bytes.get(..len).unwrap_or(&[])) {
        black_box(settings.apply(&c));
        black_box(c.encode());
    }
    black_box(settings.encode());
    black_box(settings.camera().ok());
    black_box(Ack::decode(&black_box([0u8; 20])).ok());
}

/// The planar pose with integer per-point arithmetic (`f32` only).
#[cfg(feature = "pose")]
fn run_pose_integer() {
    use camgeom::homography::Homography;
    use camgeom::pose::{PlanarConfig, PlanarPoint, refine_planar_integer, solve_planar_integer};
    let Some(cam) = camera::<f32>() else { return };
    let model = points2::<f32, N>();
    let pixels = points2::<f32, N>();
    let mut scratch = black_box([PlanarPoint::ZERO; N]);
    let cfg = black_box(PlanarConfig::default());
    let (s4, d4) = (points2::<f32, 4>(), points2::<f32, 4>());
    if let Ok(h) = Homography::from_four_points(&s4, &d4) {
        black_box(solve_planar_integer(&cam, &h, &model, &pixels, &mut scratch, &cfg).ok());
    }
    if let Some(p) = pose::<f32>() {
        let focal = black_box([1.0f32, 1.0]);
        let r = refine_planar_integer(&model, &pixels, focal, &p, &mut scratch, black_box(10));
        black_box(r.ok());
    }
}

// ---------------------------------------------------------------- main

/// The generic entry points of every selected area, instantiated for `T`.
fn run_generic<T: Real>() {
    #[cfg(feature = "camera")]
    run_camera::<T>();
    #[cfg(feature = "fixed")]
    run_fixed::<T>();
    #[cfg(feature = "homography")]
    run_homography::<T>();
    #[cfg(feature = "pose")]
    run_pose::<T>();
    #[cfg(feature = "draw")]
    run_draw::<T>();
    #[cfg(feature = "twoview")]
    run_twoview::<T>();
    #[cfg(feature = "sfm")]
    run_sfm::<T>();
    #[cfg(feature = "calib")]
    run_calib::<T>();
    #[cfg(feature = "remap")]
    run_remap::<T>();
    #[cfg(feature = "vanishing")]
    run_vanishing::<T>();
}

/// The entry points of every selected area that have no scalar parameter (integer or
/// `f32` only): built with the `f32` feature.
fn run_f32_only() {
    #[cfg(feature = "pyramid")]
    run_pyramid();
    #[cfg(feature = "gradient")]
    run_gradient();
    #[cfg(feature = "corners")]
    run_corners();
    #[cfg(feature = "klt")]
    run_klt();
    #[cfg(feature = "target")]
    run_target();
    #[cfg(feature = "features")]
    run_features();
    #[cfg(feature = "warp")]
    run_warp();
    #[cfg(feature = "chessboard")]
    run_chessboard();
    #[cfg(feature = "apriltag")]
    run_apriltag();
    #[cfg(feature = "resize")]
    run_resize();
    #[cfg(feature = "pose")]
    run_pose_integer();
    #[cfg(feature = "link")]
    run_link();
    #[cfg(feature = "command")]
    run_command();
}

#[entry]
fn main() -> ! {
    // Each feature adds its entry points; with several, the binary links only if none of them
    // has a panic path.
    #[cfg(feature = "f32")]
    {
        run_generic::<f32>();
        run_f32_only();
    }
    #[cfg(feature = "f64")]
    run_generic::<f64>();
    loop {
        core::hint::spin_loop();
    }
}
