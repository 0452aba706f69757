//! KLT speed per tracked feature on the host: basketball1 → basketball2 (640x480), 21x21
//! windows, maxLevel 3 (4 levels), 30 iterations / 0.01, pyramids built beforehand (OpenCV's
//! side does the same with `buildOpticalFlowPyramid`, see `scripts/bench_klt_opencv.py`).
//! Paths: fixed and f32, derivatives per window and per level; the Rust crate
//! `optical-flow-lk` on the same points; plus the pyramid build and the Shi-Tomasi detection.
//! camgeom's buffers (scratch, level derivatives, bordered copies: [`FlowScratch`]) are made
//! once outside the timed call, as its callers keep them (the library never allocates);
//! optical-flow-lk allocates inside its call, as its API does.
//!
//! For accuracy and speed on one input, `klt_known` tracks the 278 Shi-Tomasi corners of
//! basketball1 (`fixtures/klt/basketball_corners.csv`) into basketball1 warped by the known
//! homography of the KLT tests ([`camgeom_host::known_motion`]; OpenCV's side builds the same
//! image bit for bit), and again the 100 of them whose windows stay inside the image at every
//! level ([`INTERIOR`]): camgeom's and optical-flow-lk's end points are left in
//! `target/tmp/peers/klt.json`, which `scripts/peers.py` scores against the exact motion.
//!
//! `cargo bench -p camgeom-host --bench klt`

use std::hint::black_box;

use camgeom::corners::CornerConfig;
use camgeom::klt::FlowStatus;
use camgeom::klt::LkConfig;
use camgeom_host::bench::{Answers, load_rows};
use camgeom_host::data_dir;
use camgeom_host::images::load_gray;
use camgeom_host::klt::{
    Derivatives, FlowScratch, Path, corners, flow_pyramids, flow_pyramids_in, levels, pyramid,
};
use camgeom_host::known_motion::{warp, warps};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use serde_json::json;

/// The distance from every edge (pixels of level 0) of the interior corners: at level 3 the
/// window's half-width and two pixels, `8 (10 + 2)`, so that no window of a corner leaves the
/// image at any level while it moves a few pixels. `scripts/peers.py` selects the same ones.
const INTERIOR: f64 = 96.0;

fn bench(c: &mut Criterion) {
    let mb = data_dir().join("middlebury");
    let a = load_gray(mb.join("basketball1.png")).unwrap();
    let b = load_gray(mb.join("basketball2.png")).unwrap();
    let xy = |file: &str| -> Vec<[f64; 2]> {
        load_rows(&data_dir().join("fixtures/klt").join(file), &["x", "y"])
            .iter()
            .map(|r| [r[0], r[1]])
            .collect()
    };
    let pts = xy("basketball_bench_pts.csv");
    let cfg = LkConfig::default();
    let l = levels(&cfg);
    let (mut ba, mut bb) = (Vec::new(), Vec::new());
    let pa = pyramid(&a, &mut ba, l);
    let pb = pyramid(&b, &mut bb, l);

    let to_image = |g: &camgeom_host::images::GrayImage| {
        image::GrayImage::from_raw(g.width as u32, g.height as u32, g.data.clone()).unwrap()
    };
    let oa = optical_flow_lk::build_pyramid(&to_image(&a), l);
    let ob = optical_flow_lk::build_pyramid(&to_image(&b), l);
    // The peer crate's parameters: 21x21, 30 iterations, its default texture threshold.
    let params = optical_flow_lk::TrackParams {
        window_size: 21,
        max_iterations: 30,
        min_eigen_threshold: optical_flow_lk::DEFAULT_MIN_EIGEN_THRESHOLD,
    };
    let to_peer = |p: &[[f64; 2]]| -> Vec<(f32, f32)> {
        p.iter().map(|q| (q[0] as f32, q[1] as f32)).collect()
    };

    let mut g = c.benchmark_group("klt_flow");
    g.sample_size(20);
    for n in [100usize, 1000] {
        let p = &pts[..n.min(pts.len())];
        g.throughput(Throughput::Elements(p.len() as u64));
        for (name, path, derivs) in [
            ("fixed_window", Path::Fixed, Derivatives::Window),
            ("f32_window", Path::F32, Derivatives::Window),
            ("fixed_level", Path::Fixed, Derivatives::Level),
            ("f32_level", Path::F32, Derivatives::Level),
            ("fixed_auto", Path::Fixed, Derivatives::Auto),
            ("f32_auto", Path::F32, Derivatives::Auto),
        ] {
            // The caller's buffers made once, as a caller of the allocation-free library
            // keeps them from frame to frame.
            let mut fs = FlowScratch::new(&pa, &cfg, derivs);
            g.bench_with_input(BenchmarkId::new(name, n), &p, |bn, p| {
                bn.iter(|| flow_pyramids_in(&mut fs, &pa, &pb, black_box(p), &cfg, path).unwrap())
            });
        }
        // The peer crate optical-flow-lk on the same points, pyramids and window (its pyramid
        // built beforehand too; 4 levels).
        let op = to_peer(p);
        g.bench_with_input(BenchmarkId::new("optical_flow_lk", n), &op, |bn, op| {
            bn.iter(|| optical_flow_lk::calc_optical_flow_ex(&oa, &ob, black_box(op), None, params))
        });
    }
    g.finish();

    // Known motion: basketball1 and its warp by the test homography, same configuration.
    let (_, h) = warps(a.width, a.height)
        .into_iter()
        .find(|(name, _)| *name == "homography")
        .expect("the homography warp");
    let w = warp(&a, &h);
    let mut bw = Vec::new();
    let pw = pyramid(&w, &mut bw, l);
    let ow = optical_flow_lk::build_pyramid(&to_image(&w), l);
    let known = xy("basketball_corners.csv");
    let mut answers = Answers::new(env!("CARGO_TARGET_TMPDIR"), "klt");
    let mut g = c.benchmark_group("klt_known");
    g.sample_size(20);
    // The corners and those whose windows stay inside the image at every level
    // ([`INTERIOR`]): optical-flow-lk skips a window that leaves the image (its point is lost
    // at that level), where camgeom, as OpenCV, reflects the image and tracks on.
    let interior: Vec<[f64; 2]> = known
        .iter()
        .copied()
        .filter(|p| {
            p.iter()
                .zip([w.width, w.height])
                .all(|(&v, n)| v >= INTERIOR && v <= (n - 1) as f64 - INTERIOR)
        })
        .collect();
    for (set, pts) in [("homography", &known), ("homography_interior", &interior)] {
        g.throughput(Throughput::Elements(pts.len() as u64));
        for (name, path) in [("fixed", Path::Fixed), ("f32", Path::F32)] {
            let res = flow_pyramids(&pa, &pw, pts, &cfg, path, Derivatives::Auto).unwrap();
            let end: Vec<Option<[f64; 2]>> = res
                .iter()
                .map(|f| (f.status == FlowStatus::Tracked).then_some([f.x, f.y]))
                .collect();
            answers.record(&format!("{set}/{name}"), json!({ "points": end }));
            let mut fs = FlowScratch::new(&pa, &cfg, Derivatives::Auto);
            g.bench_function(BenchmarkId::new(name, set), |bn| {
                bn.iter(|| flow_pyramids_in(&mut fs, &pa, &pw, black_box(pts), &cfg, path).unwrap())
            });
        }
        let op = to_peer(pts);
        let res = optical_flow_lk::calc_optical_flow_ex(&oa, &ow, &op, None, params);
        let end: Vec<Option<[f64; 2]>> = res
            .iter()
            .map(|r| {
                (r.status == optical_flow_lk::TrackStatus::Tracked)
                    .then_some([f64::from(r.pos.0), f64::from(r.pos.1)])
            })
            .collect();
        answers.record(&format!("{set}/optical_flow_lk"), json!({ "points": end }));
        g.bench_function(BenchmarkId::new("optical_flow_lk", set), |bn| {
            bn.iter(|| {
                optical_flow_lk::calc_optical_flow_ex(&oa, &ow, black_box(&op), None, params)
            })
        });
    }
    g.finish();

    // The pyramid's levels (FNV-1a of each level's bytes) and the corners, for the peer
    // table's comparison with `cv2.pyrDown` and `cv2.goodFeaturesToTrack`.
    let mut buf = Vec::new();
    let p = pyramid(&a, &mut buf, 4);
    let levels: Vec<String> = (1..p.len())
        .filter_map(|l| p.level(l))
        .map(|l| {
            let bytes = (0..l.height()).filter_map(|y| l.row(y)).flatten();
            let h = camgeom_host::bench::fnv1a(bytes.map(|&b| u64::from(b)));
            format!("{h:016x}")
        })
        .collect();
    answers.record("pyramid/basketball1", json!({ "fnv1a": levels }));
    let ccfg = CornerConfig {
        quality: 0.01,
        min_distance: 10,
        max_corners: 0,
    };
    let found = corners(&a, &ccfg, 400).unwrap();
    answers.record("good_features/basketball1", json!({ "corners": found }));
    answers.save();

    let mut g = c.benchmark_group("klt_setup");
    g.sample_size(20);
    g.bench_function("pyramid_640x480_4_levels", |bn| {
        let mut buf = Vec::new();
        bn.iter(|| {
            let p = pyramid(black_box(&a), &mut buf, 4);
            black_box(p.len())
        })
    });
    g.bench_function("good_features_640x480_400", |bn| {
        bn.iter(|| corners(black_box(&a), &ccfg, 400).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
