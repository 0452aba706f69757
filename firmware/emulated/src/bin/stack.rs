//! Worst-case stack use of camgeom's firmware entry points, measured by stack painting on the
//! emulated Cortex-M7: for each entry point, [`measure`] fills the free stack below the
//! current stack pointer with a pattern, calls the entry point once on a worst-ish input of
//! the sizes the firmware uses (320x240 frames, 4 pyramid levels, 21x21 KLT window, 32 and 200
//! features, 500 RANSAC samples, 100 two-view pairs and three-view tracks; 160x120 for the tag
//! detector, the undistortion map and the chessboard, whose 320x240 buffers do not fit beside
//! the others), then finds the lowest word no longer holding the pattern.
//! The distance from the stack pointer at the call to that word is the entry point's
//! high-water mark (its own frames and everything it calls, plus the few bytes of the closure
//! that forwards the arguments).
//!
//! Inputs that would otherwise sit in the caller's frame are statics, so only the callee's use
//! is counted. Logs one `stack <name>: <bytes> bytes` line per entry point and the summary
//! `stack table: <n> entry points`. Run it with `cargo xtask stack` (BENCHMARKS.md, "Stack").
#![no_std]
#![no_main]

use camgeom_fw_emulated::{board, cost};

use core::hint::black_box;

use camgeom::apriltag::{Detector, DetectorConfig, families};
use camgeom::calib::{CalibrationParams, Calibrator};
use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::chessboard::{BoardSize, ChessboardDetector, DetectParams};
use camgeom::corners::{self, Corner, CornerConfig, good_features};
use camgeom::draw::{WireframeParams, cube, draw_wireframe};
use camgeom::heapless::Vec;
use camgeom::homography::{dlt, find_homography};
use camgeom::image::{ImageMut, ImageView};
use camgeom::klt::{Borders, Fixed, Flow, Gradients, LkConfig, Q16, calc_flow, scratch_len};
use camgeom::nalgebra::{ComplexField, Point2, Point3, Vector3};
use camgeom::pose::{
    PlanarConfig, PlanarPoint, solve_planar, solve_planar_integer, solve_pnp_ransac,
};
use camgeom::pyramid::{Pyramid, buffer_len};
use camgeom::ransac::RansacConfig;
use camgeom::remap::{GridMap, grid_len, new_camera_matrix};
use camgeom::rng::Pcg32;
use camgeom::sfm::{SfmParams, SfmWorkspace, Track, reconstruct_three_views};
use camgeom::target::{
    GivenCorners, PlanarTarget, TargetConfig, TargetParams, corner_scratch_len, flow_scratch_len,
};
use camgeom::transform::{Pose, Transform};
use camgeom::twoview::{
    View1, eight_point, find_essential, find_fundamental, five_point, recover_pose, seven_point,
    triangulate_dlt, triangulate_optimal,
};
use camgeom_fw_app::texture::textured_frame;
use camgeom_fw_emulated::entry;

use static_cell::{ConstStaticCell, StaticCell};

const W: usize = 320;
const H: usize = 240;
const LEVELS: usize = 4;
const WIN: usize = 21;
const CANDIDATES: usize = 512;
/// Feature counts: the planar target's and the tracker's.
const N_TARGET: usize = 32;
const N_TRACK: usize = 200;
/// Exactly this many RANSAC samples (confidence 1: no early stop).
const RANSAC_ITERATIONS: u32 = 500;
/// Two-view correspondences (and three-view tracks).
const N_PAIRS: usize = 100;
/// E-RANSAC samples: each is a 5-point solve in software `f64`, ~15M instructions.
const E_RANSAC_ITERATIONS: u32 = 20;
/// The pattern painted below the stack pointer: cortex-m-rt's, so that
/// [`board::stack_usage`] still reads the whole run's high-water mark at the end.
const PAINT: u32 = cortex_m_rt::STACK_PAINT_VALUE;
/// Bytes left unpainted just below the stack pointer of [`measure`] (its own loop).
const GUARD: usize = 64;

unsafe extern "C" {
    /// Bottom of the stack region (end of static RAM), from cortex-m-rt's `link.x`.
    static _stack_end: u32;
}

fn sp() -> usize {
    let sp: usize;
    // SAFETY: reads the stack pointer register; no memory access.
    unsafe { core::arch::asm!("mov {}, sp", out(reg) sp, options(nomem, nostack)) };
    sp
}

/// Calls `f` once on a painted stack; returns its result and its stack high-water mark in
/// bytes (from the stack pointer at the call down to the deepest word written).
#[inline(never)]
fn measure<R>(f: impl FnOnce() -> R) -> (R, u32) {
    let bottom = (&raw const _stack_end) as usize;
    let top = sp();
    let paint_end = (top - GUARD) & !3;
    let mut p = bottom;
    while p < paint_end {
        // SAFETY: word-aligned addresses between the bottom of the stack region and below the
        // live stack: free stack RAM that nothing else uses while this loop runs.
        unsafe { (p as *mut u32).write_volatile(PAINT) };
        p += 4;
    }
    let r = black_box(call(f));
    let mut low = bottom;
    while low < paint_end {
        // SAFETY: as above; reading back the painted region.
        if unsafe { (low as *const u32).read_volatile() } != PAINT {
            break;
        }
        low += 4;
    }
    if low == bottom {
        defmt::error!("stack overflowed into the bottom of the region");
        board::exit_failure()
    }
    (r, (top - low) as u32)
}

/// Calls `f` in a frame of its own, below [`measure`]'s stack pointer reading: were `f`
/// inlined into [`measure`], its locals would sit in [`measure`]'s frame and go uncounted.
#[inline(never)]
fn call<R>(f: impl FnOnce() -> R) -> R {
    f()
}

const PYR_LEN: usize = buffer_len(W, H, LEVELS);
static FRAME_A: ConstStaticCell<[u8; W * H]> = ConstStaticCell::new([0; W * H]);
static FRAME_B: ConstStaticCell<[u8; W * H]> = ConstStaticCell::new([0; W * H]);
/// The undistorted frame, then the rendered chessboard: 160x120, RAM for a third 320x240 frame
/// would be taken from the stack.
const CW: usize = 160;
const CH: usize = 120;
static FRAME_C: ConstStaticCell<[u8; CW * CH]> = ConstStaticCell::new([0; CW * CH]);
static PYR_A: ConstStaticCell<[u8; PYR_LEN]> = ConstStaticCell::new([0; PYR_LEN]);
static PYR_B: ConstStaticCell<[u8; PYR_LEN]> = ConstStaticCell::new([0; PYR_LEN]);
static FLOW_SCRATCH: ConstStaticCell<[i16; scratch_len(WIN)]> =
    ConstStaticCell::new([0; scratch_len(WIN)]);
static CORNER_SCRATCH: ConstStaticCell<[u32; corners::scratch_len(W)]> =
    ConstStaticCell::new([0; corners::scratch_len(W)]);
const NO_CORNER: Corner = Corner {
    x: 0,
    y: 0,
    score: 0,
};
static CANDIDATE_BUF: ConstStaticCell<[Corner; CANDIDATES]> =
    ConstStaticCell::new([NO_CORNER; CANDIDATES]);
static CORNERS_OUT: ConstStaticCell<Vec<Corner, N_TRACK>> = ConstStaticCell::new(Vec::new());
static FIXED_PTS: ConstStaticCell<[[Q16; 2]; N_TRACK]> =
    ConstStaticCell::new([[Q16::ZERO; 2]; N_TRACK]);
static FIXED_FLOWS: ConstStaticCell<[Flow<Q16>; N_TRACK]> = ConstStaticCell::new(
    [Flow {
        x: Q16::ZERO,
        y: Q16::ZERO,
        status: camgeom::klt::FlowStatus::Tracked,
        err: Q16::ZERO,
    }; N_TRACK],
);
static F32_PTS: ConstStaticCell<[[f32; 2]; N_TRACK]> = ConstStaticCell::new([[0.0; 2]; N_TRACK]);
static F32_FLOWS: ConstStaticCell<[Flow<f32>; N_TRACK]> = ConstStaticCell::new(
    [Flow {
        x: 0.0,
        y: 0.0,
        status: camgeom::klt::FlowStatus::Tracked,
        err: 0.0,
    }; N_TRACK],
);
const ORIGIN2: Point2<f32> = Point2::new(0.0, 0.0);
static H_SRC: ConstStaticCell<[Point2<f32>; N_TRACK]> = ConstStaticCell::new([ORIGIN2; N_TRACK]);
static H_DST: ConstStaticCell<[Point2<f32>; N_TRACK]> = ConstStaticCell::new([ORIGIN2; N_TRACK]);
static H_MASK: ConstStaticCell<[bool; N_TRACK]> = ConstStaticCell::new([false; N_TRACK]);
/// The planar target with its work buffers (the default 15x15 windows fit the 21x21 scratch).
type Target =
    PlanarTarget<Fixed, N_TARGET, { flow_scratch_len(WIN) }, { corner_scratch_len(W) }, CANDIDATES>;
static TARGET: ConstStaticCell<Target> = ConstStaticCell::new(Target::new());
static SFM: ConstStaticCell<Option<SfmWorkspace<f32, N_PAIRS>>> = ConstStaticCell::new(None);
/// The chessboard rows: a 9x6 board (inner corners), the calibration firmware's detector and
/// calibrator (16 views of up to 64 corners).
const BOARD: (usize, usize) = (9, 6);
const BOARD_CORNERS: usize = BOARD.0 * BOARD.1;
const CALIB_VIEWS: usize = 8;
static BOARD_DETECTOR: ConstStaticCell<ChessboardDetector<512>> =
    ConstStaticCell::new(ChessboardDetector::new());
static BOARD_SCRATCH: ConstStaticCell<[i32; camgeom::chessboard::scratch_len(CW)]> =
    ConstStaticCell::new([0; camgeom::chessboard::scratch_len(CW)]);
static CALIBRATOR: StaticCell<Calibrator<f32, 16, 64>> = StaticCell::new();
/// The tag detector's memory for a 160x120 frame (level 1 of the pyramid): the 320x240
/// workspace (119 KB) does not fit beside this binary's frames and pyramids.
type TagWorkspace = camgeom::apriltag::Workspace<
    160,
    { camgeom::apriltag::tiles_len(160, 120, 1) },
    2048,
    128,
    4096,
    { camgeom::apriltag::sort_len(160, 120, 1) },
>;
static TAG_WORKSPACE: ConstStaticCell<TagWorkspace> = ConstStaticCell::new(TagWorkspace::new());
/// Grid undistortion map, nodes every 2^3 px.
const GRID_SHIFT: u32 = 3;
static GRID: ConstStaticCell<[[i32; 2]; grid_len(CW, CH, GRID_SHIFT)]> =
    ConstStaticCell::new([[0; 2]; grid_len(CW, CH, GRID_SHIFT)]);

fn fail(what: &str, e: camgeom::Error) -> ! {
    defmt::error!("{=str}: {}", what, e);
    board::exit_failure()
}

/// Draws a 10x7-square chessboard (9x6 inner corners) of 11 px squares, turned by 0.1 rad, on
/// grey into a `CW`x`CH` frame: black and white squares with a one-pixel linear edge.
fn render_board(frame: &mut [u8]) {
    const SQ: f32 = 11.0;
    let (c, s) = (0.1f32.cos(), 0.1f32.sin());
    let (cx, cy) = (CW as f32 / 2.0, CH as f32 / 2.0);
    for (i, px) in frame.iter_mut().enumerate() {
        let (x, y) = ((i % CW) as f32 - cx, (i / CW) as f32 - cy);
        // Board coordinates in squares, origin at the board's corner.
        let (u, v) = ((c * x + s * y) / SQ + 5.0, (-s * x + c * y) / SQ + 3.5);
        *px = if !(0.0..10.0).contains(&u) || !(0.0..7.0).contains(&v) {
            128
        } else {
            // Distance to the nearest square edge in pixels, signed by the square's colour.
            let (fu, fv) = (u - u.floor(), v - v.floor());
            let du = SQ * fu.min(1.0 - fu);
            let dv = SQ * fv.min(1.0 - fv);
            let black = (u.floor() as i32 + v.floor() as i32) % 2 == 0;
            let t = du.min(dv).min(1.0) * 0.5 + 0.5;
            let t = if black { 1.0 - t } else { t };
            (t * 255.0) as u8
        };
    }
}

fn row(name: &str, bytes: u32, rows: &mut u32) {
    defmt::info!("stack {=str}: {=u32} bytes", name, bytes);
    *rows += 1;
}

#[entry]
fn main() -> ! {
    cost::start();
    let mut rows = 0u32;
    let frame_a = FRAME_A.take();
    let frame_b = FRAME_B.take();
    let frames = ImageMut::packed(&mut frame_a[..], W, H)
        .map(|mut a| textured_frame(&mut a, 0, 0))
        .and_then(|()| ImageMut::packed(&mut frame_b[..], W, H))
        .map(|mut b| textured_frame(&mut b, 300, -170));
    if let Err(e) = frames {
        fail("frames", e)
    }

    // ---- camera ----
    let k = match Intrinsics::new(300.0f32, 300.0, 159.5, 119.5) {
        Ok(k) => k,
        Err(e) => fail("intrinsics", e),
    };
    let dist = match Distortion::from_opencv([-0.28f32, 0.07, 1e-3, -5e-4, 0.0]) {
        Ok(d) => d,
        Err(e) => fail("distortion", e),
    };
    let camera = black_box(Camera::new(k, dist));
    let pose = match Pose::from_rodrigues(
        Vector3::new(0.2f32, -0.1, 0.05),
        Vector3::new(-0.1f32, -0.08, 0.35),
    ) {
        Ok(p) => black_box(p),
        Err(e) => fail("pose", e),
    };
    let x = black_box(Point3::new(0.05f32, 0.04, 0.0));
    let (_, s) = measure(|| camera.project(&pose, &x));
    row("Camera::project", s, &mut rows);
    let u = black_box(Point2::new(300.0f32, 20.0));
    let (_, s) = measure(|| camera.back_project(&u));
    row("Camera::back_project (distorted, Newton)", s, &mut rows);

    // ---- the cube (drawn into frame B before its views exist) ----
    let (vertices, edges) = cube(0.05f32, 0.025, 0.1);
    let wire = black_box(WireframeParams::default());
    let (r, s) = measure(|| {
        let mut img = ImageMut::packed(&mut frame_b[..], W, H)?;
        draw_wireframe(&mut img, &camera, &pose, &vertices, &edges, &wire)
    });
    row("draw_wireframe cube, 8 segments", s, &mut rows);
    if let Err(e) = r {
        fail("draw_wireframe", e)
    }

    // ---- pyramids ----
    let pyr_a = PYR_A.take();
    let pyr_b = PYR_B.take();
    let va = match ImageView::packed(&frame_a[..], W, H) {
        Ok(v) => black_box(v),
        Err(e) => fail("view A", e),
    };
    let vb = match ImageView::packed(&frame_b[..], W, H) {
        Ok(v) => black_box(v),
        Err(e) => fail("view B", e),
    };
    let (pa, s) = measure(|| Pyramid::build(va, &mut pyr_a[..], LEVELS));
    row("Pyramid::build 320x240, 4 levels", s, &mut rows);
    let pa = match pa {
        Ok(p) => p,
        Err(e) => fail("pyramid A", e),
    };
    let pb = match Pyramid::build(vb, &mut pyr_b[..], LEVELS) {
        Ok(p) => p,
        Err(e) => fail("pyramid B", e),
    };

    // ---- corners ----
    let cand = CANDIDATE_BUF.take();
    let cscr = CORNER_SCRATCH.take();
    let out = CORNERS_OUT.take();
    let ccfg = match black_box(CornerConfig {
        quality: 0.01,
        min_distance: 8,
        max_corners: N_TRACK,
    })
    .check()
    {
        Ok(p) => p,
        Err(e) => fail("CornerConfig::check", e),
    };
    let (n, s) = measure(|| {
        good_features(
            &va,
            &ccfg,
            core::iter::empty(),
            out,
            &mut cand[..],
            &mut cscr[..],
        )
    });
    row(
        "good_features 320x240, 512 candidates, 200 out",
        s,
        &mut rows,
    );
    if let Err(e) = n {
        fail("good_features", e)
    }

    // ---- KLT, 200 points on a grid, 21x21, max level 3 ----
    let fscr = FLOW_SCRATCH.take();
    let cfg = match LkConfig::default().check() {
        Ok(c) => black_box(c),
        Err(e) => fail("lk", e),
    };
    let fpts = FIXED_PTS.take();
    let ffl = FIXED_FLOWS.take();
    let gpts = F32_PTS.take();
    let gfl = F32_FLOWS.take();
    for (k, (fp, gp)) in fpts.iter_mut().zip(gpts.iter_mut()).enumerate() {
        let (i, j) = (k % 20, k / 20);
        let x = 24 + (i * (W - 48)) / 19;
        let y = 24 + (j * (H - 48)) / 9;
        *fp = [
            Q16::saturating_from_f32(x as f32),
            Q16::saturating_from_f32(y as f32),
        ];
        *gp = [x as f32, y as f32];
    }
    let (r, s) = measure(|| {
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &fpts[..],
            &mut ffl[..],
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut fscr[..],
        )
    });
    row("calc_flow::<Fixed> 200 points", s, &mut rows);
    if let Err(e) = r {
        fail("calc_flow fixed", e)
    }
    let (r, s) = measure(|| {
        calc_flow::<f32>(
            &pa,
            &pb,
            &gpts[..],
            &mut gfl[..],
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut fscr[..],
        )
    });
    row("calc_flow::<f32> 200 points", s, &mut rows);
    if let Err(e) = r {
        fail("calc_flow f32", e)
    }

    // ---- homography RANSAC, 200 points, half outliers, exactly 500 samples ----
    let src = H_SRC.take();
    let dst = H_DST.take();
    let mask = H_MASK.take();
    let mut g = Pcg32::new(0x5354_4143_4b00);
    for (i, (s, d)) in src.iter_mut().zip(dst.iter_mut()).enumerate() {
        let p = Point2::new(g.uniform(0.0, 320.0) as f32, g.uniform(0.0, 240.0) as f32);
        *s = p;
        *d = if i % 2 == 0 {
            Point2::new(
                0.93 * p.x - 0.11 * p.y + 31.0,
                0.06 * p.x + 1.04 * p.y - 17.0,
            )
        } else {
            Point2::new(g.uniform(0.0, 320.0) as f32, g.uniform(0.0, 240.0) as f32)
        };
    }
    let rcfg = match black_box(RansacConfig {
        threshold: 2.0f32,
        confidence: 1.0,
        max_iterations: RANSAC_ITERATIONS,
        ..RansacConfig::default()
    })
    .check()
    {
        Ok(p) => p,
        Err(e) => fail("RansacConfig::check", e),
    };
    let (r, s) = measure(|| find_homography(&src[..], &dst[..], &rcfg, &mut mask[..]));
    row("find_homography 200 points, 500 samples", s, &mut rows);
    if let Err(e) = r {
        fail("find_homography", e)
    }

    // ---- pose: 32 target points seen through the distorted camera ----
    let model: [Point2<f32>; N_TARGET] =
        core::array::from_fn(|k| Point2::new((k % 8) as f32 * 0.025, (k / 8) as f32 * 0.035));
    let mut pixels = [ORIGIN2; N_TARGET];
    for (u, m) in pixels.iter_mut().zip(model.iter()) {
        match camera.project(&pose, &Point3::new(m.x, m.y, 0.0)) {
            Ok(p) => *u = p,
            Err(e) => fail("project", e),
        }
    }
    let (model, pixels) = black_box((model, pixels));
    let mut scratch = [ORIGIN2; N_TARGET];
    let pcfg = black_box(PlanarConfig::default());
    let (r, s) = measure(|| solve_planar(&camera, &model, &pixels, &mut scratch, &pcfg));
    row("solve_planar 32 points", s, &mut rows);
    if let Err(e) = r {
        fail("solve_planar", e)
    }
    let hint = match dlt(&model, &pixels) {
        Ok(h) => black_box(h),
        Err(e) => fail("dlt", e),
    };
    let mut points = [PlanarPoint::ZERO; N_TARGET];
    let (r, s) =
        measure(|| solve_planar_integer(&camera, &hint, &model, &pixels, &mut points, &pcfg));
    row("solve_planar_integer 32 points", s, &mut rows);
    if let Err(e) = r {
        fail("solve_planar_integer", e)
    }
    let world: [Point3<f32>; N_TARGET] = core::array::from_fn(|k| {
        let m = model.get(k).copied().unwrap_or(ORIGIN2);
        Point3::new(m.x, m.y, if k % 3 == 0 { 0.02 } else { 0.0 })
    });
    let mut wpix = [ORIGIN2; N_TARGET];
    for (u, x) in wpix.iter_mut().zip(world.iter()) {
        match camera.project(&pose, x) {
            Ok(p) => *u = p,
            Err(e) => fail("project", e),
        }
    }
    let mut pmask = [false; N_TARGET];
    let (r, s) =
        measure(|| solve_pnp_ransac(&camera, &world, &wpix, &mut scratch, &rcfg, &mut pmask));
    row("solve_pnp_ransac 32 points, 500 samples", s, &mut rows);
    if let Err(e) = r {
        fail("solve_pnp_ransac", e)
    }

    // ---- one planar-target frame (KLT both ways, RANSAC, IPPE + LM, re-detection) ----
    let target = TARGET.take();
    let params = match TargetParams::new(&TargetConfig::default(), Camera::pinhole(k), [0.2, 0.15])
    {
        Ok(p) => black_box(p),
        Err(e) => fail("target", e),
    };
    let rect = [
        (70.0f32, 50.0f32),
        (250.0, 50.0),
        (250.0, 185.0),
        (70.0, 185.0),
    ]
    .map(|(x, y)| Point2::new(x, y));
    let mut given = GivenCorners::new(rect);
    let (r, s) = measure(|| target.step(&params, None, &pa, &mut given, &mut ()));
    row(
        "PlanarTarget::<Fixed, 32>::step (acquisition)",
        s,
        &mut rows,
    );
    if let Err(e) = r {
        fail("target acquisition", e)
    }
    let (r, s) = measure(|| target.step(&params, Some(&pa), &pb, &mut given, &mut ()));
    row("PlanarTarget::<Fixed, 32>::step", s, &mut rows);
    if let Err(e) = r {
        fail("target step", e)
    }
    // ---- two-view: 100 pairs of a camera moving sideways, every other one an outlier ----
    let kp = match Intrinsics::new(600.0f32, 600.0, 320.0, 240.0) {
        Ok(k) => black_box(k),
        Err(e) => fail("intrinsics", e),
    };
    let rel = |r: [f32; 3], t: [f32; 3]| match Pose::from_rodrigues(r.into(), t.into()) {
        Ok(p) => p,
        Err(e) => fail("pose", e),
    };
    // World = view 1; views 2 and 3 to its right and above.
    let views = [
        rel([0.04, -0.12, 0.03], [-0.8, 0.1, 0.2]),
        rel([-0.05, 0.1, 0.02], [0.3, -0.7, 0.1]),
    ];
    let mut g2 = Pcg32::new(0x7477_6f76);
    let mut see = |pose: Option<&Pose<f32>>, x: &Point3<f32>| {
        let c = pose.map_or(*x, |p| p.apply(x));
        let u = kp.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
        Point2::new(
            u.x + 0.5 * g2.normal() as f32,
            u.y + 0.5 * g2.normal() as f32,
        )
    };
    let mut tracks: [Track<f32>; N_PAIRS] = [[None; 3]; N_PAIRS];
    let (mut xa, mut xb) = ([ORIGIN2; N_PAIRS], [ORIGIN2; N_PAIRS]);
    let mut gx = Pcg32::new(0x7477_0001);
    for (i, ((t, a), b)) in tracks
        .iter_mut()
        .zip(xa.iter_mut())
        .zip(xb.iter_mut())
        .enumerate()
    {
        let x = Point3::new(
            gx.uniform(-2.0, 2.0) as f32,
            gx.uniform(-1.5, 1.5) as f32,
            gx.uniform(4.0, 8.0) as f32,
        );
        let [v2, v3] = &views;
        *t = [
            Some(see(None, &x)),
            Some(see(Some(v2), &x)),
            Some(see(Some(v3), &x)),
        ];
        *a = t[0].unwrap_or(ORIGIN2);
        *b = if i % 2 == 0 {
            t[1].unwrap_or(ORIGIN2)
        } else {
            Point2::new(gx.uniform(0.0, 640.0) as f32, gx.uniform(0.0, 480.0) as f32)
        };
    }
    let (xa, xb) = black_box((xa, xb));
    // Minimal samples from the inliers (even indices); the 5-point solver takes normalised
    // coordinates.
    let pick = |x: &[Point2<f32>; N_PAIRS], k: usize| x.get(2 * k).copied().unwrap_or(ORIGIN2);
    let norm = |p: Point2<f32>| kp.pixel_to_normalized(&p).unwrap_or(ORIGIN2);
    let (s7a, s7b) = black_box((
        core::array::from_fn::<_, 7, _>(|k| pick(&xa, k)),
        core::array::from_fn::<_, 7, _>(|k| pick(&xb, k)),
    ));
    let (s5a, s5b) = black_box((
        core::array::from_fn::<_, 5, _>(|k| norm(pick(&xa, k))),
        core::array::from_fn::<_, 5, _>(|k| norm(pick(&xb, k))),
    ));
    let (r, s) = measure(|| eight_point(&xa[..], &xb[..]));
    row("eight_point 100 pairs", s, &mut rows);
    if let Err(e) = r {
        fail("eight_point", e)
    }
    let (r, s) = measure(|| seven_point(&s7a, &s7b));
    row("seven_point", s, &mut rows);
    if let Err(e) = r {
        fail("seven_point", e)
    }
    let (r, s) = measure(|| five_point(&s5a, &s5b));
    row("five_point", s, &mut rows);
    if let Err(e) = r {
        fail("five_point", e)
    }
    let mut tmask = [false; N_PAIRS];
    let fcfg = black_box(RansacConfig {
        threshold: 1.0f32,
        confidence: 1.0,
        max_iterations: RANSAC_ITERATIONS,
        ..RansacConfig::default()
    });
    let fparams = match fcfg.check() {
        Ok(p) => p,
        Err(e) => fail("RansacConfig::check", e),
    };
    let (r, s) = measure(|| find_fundamental(&xa[..], &xb[..], &fparams, &mut tmask[..]));
    row("find_fundamental 100 pairs, 500 samples", s, &mut rows);
    if let Err(e) = r {
        fail("find_fundamental", e)
    }
    // E samples cost ~15M instructions each (f64 5-point in software): the depth does not
    // depend on the count.
    let ecfg = match black_box(RansacConfig {
        max_iterations: E_RANSAC_ITERATIONS,
        ..fcfg
    })
    .check()
    {
        Ok(p) => p,
        Err(e) => fail("RansacConfig::check", e),
    };
    let (r, s) = measure(|| find_essential(&kp, &kp, &xa[..], &xb[..], &ecfg, &mut tmask[..]));
    row("find_essential 100 pairs, 20 samples", s, &mut rows);
    let e = match r {
        Ok((e, _)) => e,
        Err(e) => fail("find_essential", e),
    };
    let (r, s) = measure(|| recover_pose(&e, &kp, &kp, &xa[..], &xb[..], 50.0, &mut tmask[..]));
    row("recover_pose 100 pairs", s, &mut rows);
    let recovered = match r {
        Ok(r) => r,
        Err(e) => fail("recover_pose", e),
    };
    let (p1, p2) = (Transform::<View1, View1, f32>::identity(), recovered.pose);
    let (a0, b0) = black_box((norm(pick(&xa, 0)), norm(pick(&xb, 0))));
    let (r, s) = measure(|| triangulate_dlt(&p1, &p2, &a0, &b0));
    row("triangulate_dlt", s, &mut rows);
    if let Err(e) = r {
        fail("triangulate_dlt", e)
    }
    let (r, s) = measure(|| triangulate_optimal(&p1, &p2, &a0, &b0));
    row("triangulate_optimal", s, &mut rows);
    if let Err(e) = r {
        fail("triangulate_optimal", e)
    }
    let sfm_slot = SFM.take();
    let sfm_ws = sfm_slot.insert(SfmWorkspace::new());
    let (tracks, scfg) = black_box((tracks, SfmParams::default()));
    let pin = black_box(Camera::pinhole(kp));
    let (r, s) = measure(|| reconstruct_three_views(&pin, &tracks[..], &scfg, sfm_ws));
    row(
        "reconstruct_three_views 100 tracks, 20 bundle steps",
        s,
        &mut rows,
    );
    if let Err(e) = r {
        fail("reconstruct_three_views", e)
    }

    // ---- AprilTag detection on level 1 of pyramid A (160x120), all four families ----
    let detector = match Detector::new(DetectorConfig::default(), &families::ALL) {
        Ok(d) => d,
        Err(e) => fail("tag detector", e),
    };
    let tag_ws = TAG_WORKSPACE.take();
    let Some(half) = pa.level(1) else {
        fail("pyramid level 1", camgeom::Error::InvalidImage)
    };
    let (r, s) = measure(|| detector.detect::<8>(&half, &mut tag_ws.as_mut_view()));
    row(
        "apriltag Detector::detect 160x120, 4 families",
        s,
        &mut rows,
    );
    if let Err(e) = r {
        fail("tag detection", e)
    }

    // ---- undistortion: new camera matrix, grid map, remap A ----
    let (r, s) = measure(|| new_camera_matrix(&camera, W, H, 0.0));
    row("new_camera_matrix (alpha 0, distortion)", s, &mut rows);
    let k_new = match r {
        Ok(k) => k,
        Err(e) => fail("new_camera_matrix", e),
    };
    let nodes = GRID.take();
    let frame_c = FRAME_C.take();
    let (r, s) = measure(|| GridMap::build(&camera, &k_new, CW, CH, GRID_SHIFT, &mut nodes[..]));
    row("GridMap::build 160x120, nodes every 8 px", s, &mut rows);
    let grid = match r {
        Ok(g) => g,
        Err(e) => fail("GridMap::build", e),
    };
    let (r, s) = measure(|| {
        let src = ImageView::packed(&frame_a[..], W, H)?;
        let mut out = ImageMut::packed(&mut frame_c[..], CW, CH)?;
        grid.remap(&src, &mut out, 0)
    });
    row("GridMap::remap 160x120 (of a 320x240 frame)", s, &mut rows);
    if let Err(e) = r {
        fail("GridMap::remap", e)
    }

    // ---- chessboard: a 9x6 board rendered (over the undistorted frame), detected (saddle
    // refinement) ----
    render_board(&mut frame_c[..]);
    let vc = match ImageView::packed(&frame_c[..], CW, CH) {
        Ok(v) => black_box(v),
        Err(e) => fail("board view", e),
    };
    let bsize = match BoardSize::new(BOARD.0, BOARD.1) {
        Ok(b) => b,
        Err(e) => fail("board", e),
    };
    let bdet = BOARD_DETECTOR.take();
    let bscr = BOARD_SCRATCH.take();
    let dparams = black_box(DetectParams::default());
    let (r, s) = measure(|| bdet.detect::<BOARD_CORNERS>(&vc, bsize, &dparams, &mut bscr[..]));
    row(
        "ChessboardDetector::<512>::detect 160x120, 9x6 board",
        s,
        &mut rows,
    );
    match r {
        Ok(found) => defmt::info!("chessboard found: {=bool}", found.is_some()),
        Err(e) => fail("chessboard detection", e),
    }

    // ---- calibration: the board's corners through the camera in 8 poses ----
    let calibrator = match Calibrator::new(bsize, 0.025f32, W, H) {
        Ok(c) => CALIBRATOR.init(c),
        Err(e) => fail("calibrator", e),
    };
    for v in 0..CALIB_VIEWS {
        let a = v as f32 * core::f32::consts::TAU / CALIB_VIEWS as f32;
        let view = match Pose::from_rodrigues(
            Vector3::new(0.35 * a.cos(), 0.35 * a.sin(), 0.1 * v as f32 - 0.3),
            Vector3::new(-0.1f32, -0.06, 0.45),
        ) {
            Ok(p) => p,
            Err(e) => fail("view pose", e),
        };
        let mut corners = [ORIGIN2; BOARD_CORNERS];
        for (k, c) in corners.iter_mut().enumerate() {
            let x = Point3::new(
                (k % BOARD.0) as f32 * 0.025,
                (k / BOARD.0) as f32 * 0.025,
                0.0,
            );
            match camera.project(&view, &x) {
                Ok(p) => *c = p,
                Err(e) => fail("project", e),
            }
        }
        if let Err(e) = calibrator.add_view(W, H, &corners) {
            fail("add_view", e)
        }
    }
    let ccfg = black_box(CalibrationParams::default());
    let (r, s) = measure(|| calibrator.solve(&ccfg));
    row(
        "Calibrator::<f32, 16, 64>::solve 8 views of 54 corners, Brown-Conrady",
        s,
        &mut rows,
    );
    if let Err(e) = r {
        fail("calibration", e)
    }

    let (used, size) = board::stack_usage();
    defmt::info!(
        "stack table: {=u32} entry points; the whole binary used {=u32} of {=u32} bytes of stack",
        rows,
        used,
        size
    );
    board::exit_success()
}
