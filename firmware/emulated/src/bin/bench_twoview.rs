//! Instruction counts of camgeom's two-view solvers on the emulated Cortex-M7 (QEMU
//! `mps2-an500`, `-icount shift=0`), f32 interfaces:
//!
//! - the normalised 8-point algorithm on [`EIGHT_N`] pairs,
//! - the 7-point solver (a loop of [`MINIMAL_REPS`] samples),
//! - the 5-point solver (the same loop; native `f32`),
//! - F-RANSAC and E-RANSAC on [`RANSAC_N`] pairs (50 % outliers), each configured to draw
//!   exactly [`F_ITERATIONS`] / [`E_ITERATIONS`] samples (confidence 1): enough for a 99 %
//!   chance of an all-inlier sample (`1 - (1 - 0.5⁷)⁶⁰⁰`, `1 - (1 - 0.5⁵)¹⁵⁰`),
//! - E-RANSAC as an application runs it: [`E_ADAPTIVE_N`] pairs, 50 % outliers, 1 px,
//!   confidence 0.999, the sample count adapted to the inlier ratio found (the cost the
//!   board goal "under 50M instructions" is about),
//! - `recover_pose` and optimal triangulation of [`POSE_N`] pairs,
//!
//! on a synthetic scene (camera `f = 600`, `c = (320, 240)`, depths 4..8, a sideways baseline
//! of 0.8; 0.5 px noise), each result checked against the truth, then logs the cost table and
//! the summary line `twoview bench: ... instructions`. Run with `cargo xtask bench-fw`.
#![no_std]
#![no_main]

use camgeom_fw_emulated::{board, cost};

use core::hint::black_box;

use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom::transform::Transform;
use camgeom::twoview::{
    Essential, RelativePose, View1, eight_point, find_essential, find_fundamental, five_point,
    recover_pose, seven_point, triangulate_optimal,
};
use camgeom_fw_emulated::entry;

use camgeom_fw_emulated::cost::{CostTable, measure};

const EIGHT_N: usize = 64;
/// Minimal samples solved in each measured loop.
const MINIMAL_REPS: usize = 8;
const RANSAC_N: usize = 100;
const RANSAC_OUTLIERS: usize = 50;
const F_ITERATIONS: u32 = 600;
const E_ITERATIONS: u32 = 150;
const E_ADAPTIVE_N: usize = 200;
const POSE_N: usize = 50;
const NOISE: f64 = 0.5;

/// `N` pairs `x1[i] ↔ x2[i]`.
type Pairs<const N: usize> = ([Point2<f32>; N], [Point2<f32>; N]);

fn check(ok: bool, what: &str) {
    if !ok {
        defmt::error!("check failed: {=str}", what);
        board::exit_failure()
    }
}

fn fail(what: &str, e: camgeom::Error) -> ! {
    defmt::error!("{=str}: {}", what, e);
    board::exit_failure()
}

fn truth() -> RelativePose<f64> {
    match RelativePose::from_rodrigues(
        Vector3::new(0.04, -0.12, 0.03),
        Vector3::new(-0.8, 0.1, 0.2),
    ) {
        Ok(p) => p,
        Err(e) => fail("pose", e),
    }
}

/// `N` pixel pairs of the scene with `noise` px of Gaussian noise, in f32.
fn pairs<const N: usize>(g: &mut Pcg32, k: &Intrinsics<f64>, noise: f64) -> Pairs<N> {
    let pose = truth();
    let mut a = [Point2::origin(); N];
    let mut b = [Point2::origin(); N];
    for (p, q) in a.iter_mut().zip(b.iter_mut()) {
        let x = Point3::new(
            g.uniform(-2.0, 2.0),
            g.uniform(-1.5, 1.5),
            g.uniform(4.0, 8.0),
        );
        let c = pose.apply(&x);
        let u = k.normalized_to_pixel(&Point2::new(x.x / x.z, x.y / x.z));
        let v = k.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
        *p = Point2::new(u.x + noise * g.normal(), u.y + noise * g.normal()).cast();
        *q = Point2::new(v.x + noise * g.normal(), v.y + noise * g.normal()).cast();
    }
    (a, b)
}

/// Rotation error (degrees) of `r` against the truth.
fn rotation_error(p: &RelativePose<f32>) -> f32 {
    let t = truth();
    let r = p.rotation().matrix().cast::<f64>();
    let d = r * t.rotation().matrix().transpose();
    let c = ((d.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    libm_acos_deg(c)
}

/// `acos(c)` in degrees for `c` near 1: `2 asin(sqrt((1 - c) / 2))`, by the series of asin
/// (enough for the sub-degree errors checked here).
fn libm_acos_deg(c: f64) -> f32 {
    let s = ((1.0 - c) / 2.0).max(0.0);
    let x = camgeom::nalgebra::ComplexField::sqrt(s);
    let asin = x + x * x * x / 6.0 + 3.0 * x * x * x * x * x / 40.0;
    (2.0 * asin).to_degrees() as f32
}

#[entry]
fn main() -> ! {
    cost::start();
    let mut costs = CostTable::<9>::new();
    let mut g = Pcg32::new(0x5456_4657_4245_4e43);
    let k64 = match Intrinsics::new(600.0, 600.0, 320.0, 240.0) {
        Ok(k) => k,
        Err(e) => fail("intrinsics", e),
    };
    let k: Intrinsics<f32> = black_box(k64.cast());

    // Inputs through black_box: nothing may be computed before the measurements start.
    let (e8a, e8b) = black_box(pairs::<EIGHT_N>(&mut g, &k64, NOISE));
    let sevens: [Pairs<7>; MINIMAL_REPS] =
        black_box(core::array::from_fn(|_| pairs::<7>(&mut g, &k64, 0.0)));
    let fives: [Pairs<5>; MINIMAL_REPS] = black_box(core::array::from_fn(|_| {
        let (a, b) = pairs::<5>(&mut g, &k64, 0.0);
        let n = |p: &Point2<f32>| k.pixel_to_normalized(p).unwrap_or(Point2::origin());
        (a.map(|p| n(&p)), b.map(|p| n(&p)))
    }));
    let (ra, mut rb) = pairs::<RANSAC_N>(&mut g, &k64, NOISE);
    for q in rb.iter_mut().take(RANSAC_OUTLIERS) {
        *q = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)).cast();
    }
    let (ra, rb) = black_box((ra, rb));
    let (pa, pb) = black_box(pairs::<POSE_N>(&mut g, &k64, NOISE));

    // ---- 8-point ----
    let (f8, eight_cost) = measure(|| eight_point(&e8a, &e8b));
    costs.record("eight_point_64", eight_cost, EIGHT_N as u32);
    let f_true = match Essential::from_pose(&truth()).and_then(|e| e.to_fundamental(&k64, &k64)) {
        Ok(f) => f,
        Err(e) => fail("true F", e),
    };
    match f8 {
        Ok(f) => {
            // RMS Sampson distance of the noiseless pairs under the estimate.
            let (ca, cb) = pairs::<16>(&mut Pcg32::new(3), &k64, 0.0);
            let mut sq = 0.0f32;
            for (a, b) in ca.iter().zip(cb.iter()) {
                sq += f.sampson_sq(a, b).unwrap_or(f32::INFINITY);
                check(
                    f_true.sampson_sq(&a.cast(), &b.cast()).unwrap_or(1.0) < 1e-6,
                    "truth check",
                );
            }
            let rms = camgeom::nalgebra::ComplexField::sqrt(sq / 16.0);
            defmt::info!(
                "eight_point_64: RMS Sampson distance of clean pairs {=f32} px",
                rms
            );
            check(rms < 1.0, "8-point close to the truth");
        }
        Err(e) => fail("eight_point", e),
    }

    // ---- 7-point and 5-point, MINIMAL_REPS samples each ----
    let (n7, seven_cost) = measure(|| {
        let mut n = 0usize;
        for (a, b) in sevens.iter() {
            n += seven_point(a, b).map_or(0, |s| s.len());
        }
        n
    });
    costs.record("seven_point", seven_cost, MINIMAL_REPS as u32);
    let (n5, five_cost) = measure(|| {
        let mut n = 0usize;
        for (a, b) in fives.iter() {
            n += five_point(a, b).map_or(0, |s| s.len());
        }
        n
    });
    costs.record("five_point", five_cost, MINIMAL_REPS as u32);
    defmt::info!(
        "minimal solvers: {=usize} 7-point and {=usize} 5-point solutions from {=usize} samples each",
        n7,
        n5,
        MINIMAL_REPS
    );
    check(
        n7 >= MINIMAL_REPS && n5 >= MINIMAL_REPS,
        "every sample solved",
    );

    // ---- F-RANSAC and E-RANSAC, a fixed number of samples ----
    let exact = |n: u32| RansacConfig::<f32> {
        threshold: 1.0,
        confidence: 1.0,
        max_iterations: n,
        ..RansacConfig::default()
    };
    let (fcfg, ecfg) = black_box((exact(F_ITERATIONS), exact(E_ITERATIONS)));
    let (fcfg, ecfg) = match (fcfg.check(), ecfg.check()) {
        (Ok(f), Ok(e)) => (f, e),
        (Err(e), _) | (_, Err(e)) => fail("RansacConfig::check", e),
    };
    let mut mask = [false; RANSAC_N];
    let (fr, f_cost) = measure(|| find_fundamental(&ra, &rb, &fcfg, &mut mask));
    costs.record("f_ransac_100", f_cost, F_ITERATIONS);
    match fr {
        Ok((_, rep)) => {
            defmt::info!(
                "f_ransac_100: {=usize} inliers, {=u32} samples",
                rep.inliers,
                rep.iterations
            );
            check(rep.iterations == F_ITERATIONS, "F-RANSAC sample count");
            check(rep.inliers >= 40, "F-RANSAC finds the inliers");
        }
        Err(e) => fail("find_fundamental", e),
    }
    let (er, e_cost) = measure(|| find_essential(&k, &k, &ra, &rb, &ecfg, &mut mask));
    costs.record("e_ransac_100", e_cost, E_ITERATIONS);
    let e = match er {
        Ok((e, rep)) => {
            defmt::info!(
                "e_ransac_100: {=usize} inliers, {=u32} samples",
                rep.inliers,
                rep.iterations
            );
            check(rep.iterations == E_ITERATIONS, "E-RANSAC sample count");
            check(rep.inliers >= 40, "E-RANSAC finds the inliers");
            e
        }
        Err(e) => fail("find_essential", e),
    };

    // ---- E-RANSAC with the sample count adapted, 200 pairs ----
    let (ea, mut eb) = pairs::<E_ADAPTIVE_N>(&mut g, &k64, NOISE);
    for q in eb.iter_mut().step_by(2) {
        *q = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)).cast();
    }
    let (ea, eb) = black_box((ea, eb));
    let acfg = match black_box(RansacConfig::<f32> {
        threshold: 1.0,
        confidence: 0.999,
        ..RansacConfig::default()
    })
    .check()
    {
        Ok(p) => p,
        Err(e) => fail("RansacConfig::check", e),
    };
    let mut amask = [false; E_ADAPTIVE_N];
    let (ar, a_cost) = measure(|| find_essential(&k, &k, &ea, &eb, &acfg, &mut amask));
    match ar {
        Ok((_, rep)) => {
            costs.record("e_ransac_200_adaptive", a_cost, rep.iterations.max(1));
            defmt::info!(
                "e_ransac_200_adaptive: {=usize} inliers, {=u32} samples",
                rep.inliers,
                rep.iterations
            );
            check(rep.inliers >= 90, "adaptive E-RANSAC finds the inliers");
        }
        Err(e) => fail("find_essential (adaptive)", e),
    }

    // ---- recover_pose and triangulation ----
    let mut pmask = [true; POSE_N];
    let (rp, pose_cost) = measure(|| recover_pose(&e, &k, &k, &pa, &pb, 50.0, &mut pmask));
    costs.record("recover_pose_50", pose_cost, POSE_N as u32);
    let rp = match rp {
        Ok(rp) => rp,
        Err(e) => fail("recover_pose", e),
    };
    let rot = rotation_error(&rp.pose);
    defmt::info!(
        "recover_pose_50: {=usize} supporting, rotation error {=f32} deg",
        rp.supporting,
        rot
    );
    check(rot < 1.0, "pose within 1 degree");
    let p1 = Transform::<View1, View1, f32>::identity();
    let (ntri, tri_cost) = measure(|| {
        let mut n = 0usize;
        for (a, b) in pa.iter().zip(pb.iter()) {
            let (Ok(x), Ok(y)) = (k.pixel_to_normalized(a), k.pixel_to_normalized(b)) else {
                continue;
            };
            n += usize::from(triangulate_optimal(&p1, &rp.pose, &x, &y).is_ok());
        }
        n
    });
    costs.record("triangulate_optimal_50", tri_cost, POSE_N as u32);
    check(ntri >= POSE_N - 2, "triangulated");

    costs.log();
    let (stack, stack_size) = board::stack_usage();
    defmt::info!("stack: {=u32} bytes used of {=u32}", stack, stack_size);
    defmt::info!(
        "twoview bench: eight_point_64 {=u32}, seven_point {=u32}, five_point {=u32}, f_ransac_100_600it {=u32}, e_ransac_100_150it {=u32}, e_ransac_200_adaptive {=u32}, recover_pose_50 {=u32}, triangulate_optimal_50 {=u32} instructions",
        eight_cost,
        seven_cost / MINIMAL_REPS as u32,
        five_cost / MINIMAL_REPS as u32,
        f_cost,
        e_cost,
        a_cost,
        pose_cost,
        tri_cost
    );
    board::exit_success()
}
