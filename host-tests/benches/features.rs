//! Features, matching and warp timings (compare with `host-tests/scripts/bench_features.py`,
//! OpenCV with one thread on the same inputs). FAST's corners, ORB's keypoints and the warped
//! frames are left in `target/tmp/peers/` (`features.json`, `warp_*.png`), which
//! `scripts/peers.py` scores against OpenCV's on the same inputs.
//!
//! `cargo bench -p camgeom-host --bench features`

use std::hint::black_box;

use camgeom::arith::{Arithmetic, Fixed};
use camgeom::features::orb::{self, Feature, OrbParams};
use camgeom::features::{Descriptor, Match, MatchParams, fast, match_descriptors, matching};
use camgeom::heapless::Vec as HVec;
use camgeom::warp::{WarpConfig, warp_into_quad};
use camgeom_host::bench::Answers;
use camgeom_host::images::{GrayImage, load_gray, save_gray};
use criterion::{Criterion, criterion_group, criterion_main};
use serde_json::json;

fn graf1() -> GrayImage {
    load_gray(camgeom_host::data_dir().join("oxford-graf/graf1.png")).unwrap()
}

fn bench_features(c: &mut Criterion) {
    let img = graf1();
    let view = img.view().unwrap();
    let mut fscratch = vec![0u8; fast::scratch_len(img.width)];
    let mut answers = Answers::new(env!("CARGO_TARGET_TMPDIR"), "features");
    let mut found = Vec::new();
    fast::fast_detect(&view, &fast::FastParams::default(), &mut fscratch, |c| {
        found.push([c.x, c.y])
    })
    .unwrap();
    answers.record("fast/graf1", json!({ "corners": found }));
    c.bench_function("fast_t20_nonmax_graf1_800x640", |b| {
        b.iter(|| {
            let mut n = 0usize;
            fast::fast_detect(&view, &fast::FastParams::default(), &mut fscratch, |_| {
                n += 1
            })
            .unwrap();
            black_box(n)
        })
    });
    let params = OrbParams::default();
    let scale_q8 = params.config().scale_q8;
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, scale_q8)];
    let mut out: Box<HVec<Feature, 500>> = Box::default();
    orb::orb_detect(&view, &params, &mut scratch, &mut out).unwrap();
    let keypoints: Vec<[f32; 2]> = out.iter().map(|f| [f.keypoint.x, f.keypoint.y]).collect();
    answers.record("orb/graf1", json!({ "keypoints": keypoints }));
    c.bench_function("orb_500_graf1_800x640", |b| {
        b.iter(|| {
            orb::orb_detect(&view, &params, &mut scratch, &mut out).unwrap();
            black_box(out.len())
        })
    });

    let mut g = camgeom::rng::Pcg32::new(7);
    let a: Vec<Descriptor> = (0..500)
        .map(|_| Descriptor(core::array::from_fn(|_| g.next_u32())))
        .collect();
    let t: Vec<Descriptor> = (0..500)
        .map(|_| Descriptor(core::array::from_fn(|_| g.next_u32())))
        .collect();
    let mut ms = vec![Match::default(); 500];
    let mut mscratch = vec![0u32; matching::scratch_len(500)];
    c.bench_function("match_500x500_crosscheck", |b| {
        b.iter(|| {
            black_box(
                match_descriptors(&a, &t, &MatchParams::default(), &mut mscratch, &mut ms).unwrap(),
            )
        })
    });

    bench_warp::<f32>(c, &mut answers);
    bench_warp::<Fixed>(c, &mut answers);
    answers.save();
}

/// The warp of the bench logo into a 320x240 frame in arithmetic `A`.
fn bench_warp<A: Arithmetic>(c: &mut Criterion, answers: &mut Answers) {
    let (logo, quad) = camgeom_host::bench::warp_case();
    let mut frame = GrayImage::filled(320, 240, 100);
    let name = &format!("warp_128_into_320x240_{}", A::NAME);
    let cfg = WarpConfig { alpha: 255 };
    let mut once = GrayImage::filled(320, 240, 100);
    warp_into_quad::<A>(
        &logo.view().unwrap(),
        &mut once.view_mut().unwrap(),
        &quad,
        &cfg,
    )
    .unwrap();
    let png = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("peers")
        .join(format!("{name}.png"));
    std::fs::create_dir_all(png.parent().unwrap()).unwrap();
    save_gray(&once, &png).unwrap();
    answers.record(&format!("warp/{name}"), json!({ "png": png }));
    c.bench_function(name, |b| {
        b.iter(|| {
            black_box(camgeom_host::bench::warp_once::<A>(
                &logo, &mut frame, &quad, &cfg,
            ))
        })
    });
}

criterion_group!(benches, bench_features);
criterion_main!(benches);
