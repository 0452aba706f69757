//! Instruction counts of camgeom's homography solvers on the emulated Cortex-M7 (QEMU
//! `mps2-an500`, `-icount shift=0`), all in f32:
//!
//! - the exact 4-point solver (a loop of [`FOUR_POINT_REPS`] solves on different samples),
//! - the normalised DLT on [`DLT_N`] correspondences,
//! - RANSAC on [`RANSAC_N`] correspondences (50 % outliers), configured to draw exactly
//!   [`RANSAC_ITERATIONS`] samples (see [`ransac_config`]),
//!
//! then logs the cost table and the summary line `homography bench: ...`. Run it with
//! `cargo xtask bench-fw`, which also reports the flash the homography code takes (this binary
//! built with and without the `size-baseline` feature, which leaves the solver calls out).
#![no_std]
#![no_main]
// The baseline build leaves the solver calls, and what only they use, out.
#![cfg_attr(
    feature = "size-baseline",
    allow(dead_code, unused_imports, unused_mut)
)]

#[path = "../board.rs"]
mod board;
#[path = "../cost.rs"]
mod cost;

use core::hint::black_box;

use camgeom::nalgebra::{Matrix3, Point2, Vector3};
use camgeom::rng::Pcg32;
use cortex_m_rt::entry;
use defmt_semihosting as _;

use crate::cost::CostTable;
#[cfg(not(feature = "size-baseline"))]
use crate::cost::measure;

/// 4-point solves in the measured loop (one solve is below the ±40-instruction resolution's
/// comfort zone).
const FOUR_POINT_REPS: usize = 64;
/// Correspondences of the DLT.
const DLT_N: usize = 64;
/// RANSAC: correspondences, outliers among them, and the exact number of samples drawn.
const RANSAC_N: usize = 100;
const RANSAC_OUTLIERS: usize = 50;
const RANSAC_ITERATIONS: u32 = 500;
/// Noise on the destination points (pixels).
const NOISE: f64 = 0.5;

/// One sample: 4 source points and their matches.
type Quad = ([Point2<f32>; 4], [Point2<f32>; 4]);

/// The ground truth: a plane seen by two 640x480 cameras.
fn truth() -> Matrix3<f64> {
    Matrix3::new(0.93, -0.11, 31.0, 0.06, 1.04, -17.0, 1.4e-4, -1.9e-4, 1.0)
}

fn map(h: &Matrix3<f64>, p: Point2<f64>) -> Point2<f64> {
    let v = h * Vector3::new(p.x, p.y, 1.0);
    Point2::new(v.x / v.z, v.y / v.z)
}

/// `n` noisy correspondences of [`truth`], in f32.
fn correspondences<const N: usize>(g: &mut Pcg32) -> ([Point2<f32>; N], [Point2<f32>; N]) {
    let h = truth();
    let mut src = [Point2::origin(); N];
    let mut dst = [Point2::origin(); N];
    for (s, d) in src.iter_mut().zip(dst.iter_mut()) {
        let p = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        let q = map(&h, p);
        *s = p.cast();
        *d = Point2::new(q.x + NOISE * g.normal(), q.y + NOISE * g.normal()).cast();
    }
    (src, dst)
}

/// Exactly [`RANSAC_ITERATIONS`] samples: the cap, and confidence 1, which never stops early.
#[cfg(not(feature = "size-baseline"))]
fn ransac_config() -> camgeom::ransac::RansacConfig<f32> {
    camgeom::ransac::RansacConfig {
        threshold: 3.0,
        confidence: 1.0,
        max_iterations: RANSAC_ITERATIONS,
        ..camgeom::ransac::RansacConfig::default()
    }
}

fn check(ok: bool, what: &str) {
    if !ok {
        defmt::error!("check failed: {=str}", what);
        board::exit_failure()
    }
}

/// Worst distance (px) between `h` and the truth on a 80-px grid over the image.
#[cfg(not(feature = "size-baseline"))]
fn grid_gap(h: &camgeom::homography::Homography<f32>) -> f32 {
    let t = truth();
    let mut worst = 0.0f32;
    for i in 0..=8 {
        for j in 0..=6 {
            let p = Point2::new(80.0 * i as f64, 80.0 * j as f64);
            let q = map(&t, p);
            match h.transfer(&p.cast()) {
                Ok(r) => worst = worst.max((r - q.cast::<f32>()).norm()),
                Err(_) => worst = f32::INFINITY,
            }
        }
    }
    worst
}

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        defmt::error!("core peripherals already taken");
        board::exit_failure()
    };
    let cal = cost::init(cp.SYST);
    defmt::info!(
        "SysTick calibrated: {=u32} instructions in {=u32} ticks, 1 tick = {=u32} instructions",
        cal.instructions,
        cal.ticks,
        cal.per_tick
    );
    let mut costs = CostTable::<4>::new();
    let mut g = Pcg32::new(0x4642_454e_4348);

    // Inputs through black_box: nothing may be computed before the measurements start.
    let quads: [Quad; FOUR_POINT_REPS] =
        black_box(core::array::from_fn(|_| correspondences::<4>(&mut g)));
    let (dlt_src, dlt_dst) = black_box(correspondences::<DLT_N>(&mut g));
    let (r_src, mut r_dst) = correspondences::<RANSAC_N>(&mut g);
    for d in r_dst.iter_mut().take(RANSAC_OUTLIERS) {
        *d = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)).cast();
    }
    let (r_src, r_dst) = black_box((r_src, r_dst));

    #[cfg(not(feature = "size-baseline"))]
    {
        use camgeom::homography::{Homography, dlt, find_homography};

        // ---- 4-point solver ----
        let (solved, four_cost) = measure(|| {
            let mut ok = 0u32;
            for (s, d) in quads.iter() {
                ok += u32::from(Homography::from_four_points(s, d).is_ok());
            }
            ok
        });
        costs.record("four_point", four_cost, FOUR_POINT_REPS as u32);
        // A random quadrilateral may fold or be nearly collinear: most solve.
        check(
            solved as usize > FOUR_POINT_REPS / 2,
            "most 4-point samples solve",
        );
        defmt::info!(
            "four_point: {=u32} of {=usize} samples solved",
            solved,
            FOUR_POINT_REPS
        );

        // ---- DLT ----
        let (h, dlt_cost) = measure(|| dlt(&dlt_src, &dlt_dst));
        costs.record("dlt_64", dlt_cost, DLT_N as u32);
        match h {
            Ok(h) => {
                let gap = grid_gap(&h);
                defmt::info!("dlt_64: worst grid error {=f32} px", gap);
                check(gap < 2.0, "DLT close to the truth");
            }
            Err(e) => {
                defmt::error!("dlt: {}", e);
                board::exit_failure()
            }
        }

        // ---- RANSAC, exactly RANSAC_ITERATIONS samples ----
        let config = black_box(ransac_config());
        let mut mask = [false; RANSAC_N];
        let (result, ransac_cost) = measure(|| find_homography(&r_src, &r_dst, &config, &mut mask));
        costs.record("ransac_100_500it", ransac_cost, RANSAC_ITERATIONS);
        match result {
            Ok((h, report)) => {
                let gap = grid_gap(&h);
                defmt::info!(
                    "ransac: {=usize} inliers, {=u32} iterations, worst grid error {=f32} px",
                    report.inliers,
                    report.iterations,
                    gap
                );
                check(
                    report.iterations == RANSAC_ITERATIONS,
                    "RANSAC ran exactly 500 samples",
                );
                check(gap < 2.0, "RANSAC close to the truth");
            }
            Err(e) => {
                defmt::error!("ransac: {}", e);
                board::exit_failure()
            }
        }
        costs.log();
        let (stack, stack_size) = board::stack_usage();
        defmt::info!("stack: {=u32} bytes used of {=u32}", stack, stack_size);
        defmt::info!(
            "homography bench: four_point {=u32}, dlt_64 {=u32}, ransac_100_500it {=u32} instructions",
            four_cost / FOUR_POINT_REPS as u32,
            dlt_cost,
            ransac_cost
        );
    }
    #[cfg(feature = "size-baseline")]
    {
        // The same inputs, no solver: what the homography code adds is the size difference.
        black_box((&quads, &dlt_src, &dlt_dst, &r_src, &r_dst));
        costs.log();
        let (stack, stack_size) = board::stack_usage();
        defmt::info!("stack: {=u32} bytes used of {=u32}", stack, stack_size);
        check(true, "baseline");
        defmt::info!("homography bench: size baseline, no solver");
    }
    board::exit_success()
}
