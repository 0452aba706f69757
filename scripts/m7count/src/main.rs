//! Instructions of `five_point`, `find_essential`, `find_fundamental` and `eight_point` in
//! `f32` on the two-view bench inputs (`host-tests/benches/twoview.rs`: camera `f = 600`,
//! `c = (320, 240)`, 1 px, p = 0.999, the bench's seed), counted with SysTick under QEMU's
//! `-icount shift=0` (ticks x 40 = instructions; the calibration loop checks it):
//!
//! ```sh
//! cd scripts/m7count && cargo run --release
//! ```
#![no_std]
#![no_main]

use core::hint::black_box;

use camgeom::camera::Intrinsics;
use camgeom::nalgebra::Point2;
use camgeom::ransac::RansacConfig;
use camgeom::twoview::{eight_point, find_essential, find_fundamental, five_point};
use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

mod data {
    include!(concat!(env!("OUT_DIR"), "/data.rs"));
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}

/// SysTick ticks `f` takes (a 24-bit down-counter: up to 16.7M ticks, 671M instructions).
fn ticks(f: impl FnOnce()) -> u32 {
    let a = SYST::get_current();
    f();
    let b = SYST::get_current();
    a.wrapping_sub(b) & 0x00FF_FFFF
}

#[entry]
fn main() -> ! {
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00FF_FFFF);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();
    let cal = ticks(|| {
        let mut n = black_box(100_000u32);
        while n > 0 {
            n = black_box(n) - 1;
        }
    });
    hprintln!("calibration: 100000 loop iterations in {} ticks", cal);
    let per = |t: u32, n: u32| u64::from(t) * 40 / u64::from(n);
    let k = Intrinsics::<f32>::new(600.0, 600.0, 320.0, 240.0).unwrap();
    let px = |r: &[f32; 4], o: usize| Point2::new(r[o], r[o + 1]);
    let n = |p: Point2<f32>| k.pixel_to_normalized(&p).unwrap();
    let a: [Point2<f32>; 5] = core::array::from_fn(|i| n(px(&data::FIVE[i], 0)));
    let b: [Point2<f32>; 5] = core::array::from_fn(|i| n(px(&data::FIVE[i], 2)));
    let mut count = 0;
    let t = ticks(|| {
        for _ in 0..10 {
            count += five_point(black_box(&a), black_box(&b)).map_or(0, |v| v.len());
        }
    });
    hprintln!(
        "five_point: {} instructions/call, {} solutions",
        per(t, 10),
        count / 10
    );
    let x1: [Point2<f32>; 200] = core::array::from_fn(|i| px(&data::RANSAC[i], 0));
    let x2: [Point2<f32>; 200] = core::array::from_fn(|i| px(&data::RANSAC[i], 2));
    let checked = RansacConfig::<f32> {
        threshold: 1.0,
        confidence: 0.999,
        seed: 0x5eed_ca4e_0000_0001,
        ..RansacConfig::default()
    }
    .check();
    let Ok(cfg) = checked else {
        hprintln!("RansacConfig::check failed");
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    let mut mask = [false; 200];
    let mut report = (0, 0);
    let t = ticks(|| {
        report = find_essential(&k, &k, black_box(&x1), black_box(&x2), &cfg, &mut mask)
            .map_or((0, 0), |r| (r.1.inliers, r.1.iterations));
    });
    hprintln!(
        "find_essential: {} instructions, {} inliers, {} samples",
        per(t, 1),
        report.0,
        report.1
    );
    let t = ticks(|| {
        report = find_fundamental(black_box(&x1), black_box(&x2), &cfg, &mut mask)
            .map_or((0, 0), |r| (r.1.inliers, r.1.iterations));
    });
    hprintln!(
        "find_fundamental: {} instructions, {} inliers, {} samples",
        per(t, 1),
        report.0,
        report.1
    );
    let e1: [Point2<f32>; 64] = core::array::from_fn(|i| px(&data::EIGHT[i], 0));
    let e2: [Point2<f32>; 64] = core::array::from_fn(|i| px(&data::EIGHT[i], 2));
    let t = ticks(|| {
        for _ in 0..10 {
            let _ = black_box(eight_point(black_box(&e1), black_box(&e2)));
        }
    });
    hprintln!("eight_point: {} instructions/call", per(t, 10));
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}
