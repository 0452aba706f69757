//! Pose solvers on the host: the planar solver (IPPE + LM, N = 32), EPnP alone and EPnP + LM
//! (N = 50 non-coplanar points) and PnP RANSAC (N = 100, 30 % outliers, threshold 2 px, fixed
//! seed), in f32 and f64.
//!
//! The inputs are the files in `host-tests/data/fixtures/pose_bench/` (rows `X,Y,Z,u,v`:
//! world points and their pixels in the camera `f = 600`, `c = (320, 240)`, no distortion, with
//! 0.5 px Gaussian noise; `truth.csv`: the camera and each case's world-to-camera `R`, `t`),
//! which `scripts/peers.py` runs OpenCV's `solvePnP` / `solvePnPRansac` on. They come from
//! [`generate`] below; the bench checks that the files still match it, and rewrites them with
//! `CAMGEOM_WRITE_FIXTURES=1`. camgeom's poses are left in `target/tmp/peers/pose.json` for
//! the peer harness's accuracy columns.
//!
//! ```sh
//! CAMGEOM_WRITE_FIXTURES=1 cargo bench -p camgeom-host --bench pose -- --test
//! cargo bench -p camgeom-host --bench pose
//! ```

use std::hint::black_box;
use std::path::PathBuf;

use camgeom::Real;
use camgeom::camera::{Camera, Intrinsics};
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::pose::{PlanarConfig, PoseEstimate, epnp, solve_planar, solve_pnp, solve_pnp_ransac};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom::transform::Pose;
use camgeom_host::bench::{self, Answers, row_major};
use criterion::{Criterion, criterion_group, criterion_main};
use serde_json::{Value, json};

const PLANAR_N: usize = 32;
const PNP_N: usize = 50;
const RANSAC_N: usize = 100;
/// Rows with `i % 10 < OUTLIER_TENTHS` of the RANSAC input are outliers (30 %).
const OUTLIER_TENTHS: usize = 3;
/// Inlier threshold (reprojection error, px) of the RANSAC run.
pub const THRESHOLD: f64 = 2.0;
pub const CONFIDENCE: f64 = 0.999;
const SEED: u64 = 0x5eed_ca4e_0000_0001;
const NOISE: f64 = 0.5;
const COLUMNS: [&str; 5] = ["X", "Y", "Z", "u", "v"];

fn fixture_dir() -> PathBuf {
    bench::fixture_dir("pose_bench")
}

fn camera() -> Intrinsics<f64> {
    Intrinsics::new(600.0, 600.0, 320.0, 240.0).expect("camera")
}

/// The true world-to-camera pose of each case: a target tilted by ~30° at 0.6 m (planar),
/// a box of points ~1 m away seen obliquely (the others).
fn truths() -> [(&'static str, Pose<f64>); 3] {
    let p = |r: [f64; 3], t: [f64; 3]| {
        Pose::from_rodrigues(Vector3::from(r), Vector3::from(t)).expect("pose")
    };
    [
        ("planar", p([0.45, -0.25, 0.1], [-0.12, -0.08, 0.6])),
        ("pnp", p([0.2, 0.5, -0.15], [0.05, -0.04, 1.0])),
        ("ransac", p([-0.3, 0.35, 0.4], [-0.02, 0.06, 1.1])),
    ]
}

/// `(file name, text)` of every input: `planar_32.csv` (points of a 0.25 x 0.20 m target,
/// `Z = 0`), `pnp_50.csv` (a 0.4 x 0.3 x 0.3 m box), `ransac_100.csv` (the same box; rows with
/// `i % 10 < 3` get a uniform random pixel: 30 % outliers) and `truth.csv`.
fn generate() -> Vec<(String, String)> {
    let k = camera();
    let mut g = Pcg32::new(0x0050_4f53_4542);
    let [planar, pnp, ransac] = truths().map(|(_, p)| p);
    let mut rows = |pose: &Pose<f64>, n: usize, planar: bool, outliers: bool| {
        let mut s = COLUMNS.join(",") + "\n";
        for i in 0..n {
            let x = if planar {
                Point3::new(g.uniform(0.0, 0.25), g.uniform(0.0, 0.20), 0.0)
            } else {
                Point3::new(
                    g.uniform(-0.2, 0.2),
                    g.uniform(-0.15, 0.15),
                    g.uniform(-0.15, 0.15),
                )
            };
            let c = pose.apply(&x);
            let u = k.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
            let mut u = Point2::new(u.x + NOISE * g.normal(), u.y + NOISE * g.normal());
            if outliers && i % 10 < OUTLIER_TENTHS {
                u = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
            }
            s.push_str(&format!(
                "{:?},{:?},{:?},{:?},{:?}\n",
                x.x, x.y, x.z, u.x, u.y
            ));
        }
        s
    };
    let mut out = vec![
        (
            format!("planar_{PLANAR_N}.csv"),
            rows(&planar, PLANAR_N, true, false),
        ),
        (format!("pnp_{PNP_N}.csv"), rows(&pnp, PNP_N, false, false)),
        (
            format!("ransac_{RANSAC_N}.csv"),
            rows(&ransac, RANSAC_N, false, true),
        ),
    ];
    let mut truth = String::from("case,fx,fy,cx,cy,r11,r12,r13,r21,r22,r23,r31,r32,r33,t1,t2,t3\n");
    for (name, pose) in truths() {
        let mut vals: Vec<f64> = vec![k.fx(), k.fy(), k.cx(), k.cy()];
        vals.extend(row_major(pose.rotation().matrix()));
        vals.extend(pose.translation().iter());
        let vals: Vec<String> = vals.iter().map(|v| format!("{v:?}")).collect();
        truth.push_str(&format!("{name},{}\n", vals.join(",")));
    }
    out.push(("truth.csv".to_string(), truth));
    out
}

/// `(world, pixels)` of a fixture, in `T`.
fn load<T: Real>(name: &str) -> (Vec<Point3<T>>, Vec<Point2<T>>) {
    let l = T::lit;
    bench::load_rows(&fixture_dir().join(name), &COLUMNS)
        .iter()
        .map(|r| {
            (
                Point3::new(l(r[0]), l(r[1]), l(r[2])),
                Point2::new(l(r[3]), l(r[4])),
            )
        })
        .unzip()
}

fn pose_json<T: Real>(p: &Pose<T>) -> Value {
    json!({
        "R": row_major(p.rotation().matrix()),
        "t": p.translation().iter().map(|v| v.to_f64()).collect::<Vec<_>>(),
    })
}

fn estimate_json<T: Real>(e: &PoseEstimate<T>) -> Value {
    let mut v = pose_json(&e.pose);
    v["rms_px"] = json!(e.rms_px.to_f64());
    v
}

fn bench_type<T: Real>(c: &mut Criterion, ty: &str, answers: &mut Answers) {
    let cam = Camera::pinhole(camera().cast::<T>());

    let (world, px) = load::<T>(&format!("planar_{PLANAR_N}.csv"));
    let model: Vec<Point2<T>> = world.iter().map(|p| Point2::new(p.x, p.y)).collect();
    let mut scratch = vec![Point2::origin(); px.len()];
    let cfg = PlanarConfig::default();
    let sol = solve_planar(&cam, &model, &px, &mut scratch, &cfg).expect("planar bench input");
    let mut v = estimate_json(&sol.best);
    v["alternative_rms_px"] = json!(sol.alternative.rms_px.to_f64());
    answers.record(&format!("planar_{PLANAR_N}/{ty}"), v);
    c.bench_function(&format!("pose/planar_{PLANAR_N}/{ty}"), |b| {
        b.iter(|| solve_planar(&cam, black_box(&model), black_box(&px), &mut scratch, &cfg))
    });

    let (world, px) = load::<T>(&format!("pnp_{PNP_N}.csv"));
    let mut scratch = vec![Point2::origin(); px.len()];
    // EPnP alone takes undistorted normalised points (what solve_pnp computes first).
    let normalized: Vec<Point2<T>> = px
        .iter()
        .map(|u| cam.undistort_to_normalized(u).expect("normalise"))
        .collect();
    let (p, _) = epnp(&world, &normalized).expect("EPnP bench input");
    answers.record(&format!("epnp_{PNP_N}/{ty}"), pose_json(&p));
    c.bench_function(&format!("pose/epnp_{PNP_N}/{ty}"), |b| {
        b.iter(|| epnp(black_box(&world), black_box(&normalized)))
    });
    let e = solve_pnp(&cam, &world, &px, &mut scratch).expect("PnP bench input");
    answers.record(&format!("pnp_{PNP_N}/{ty}"), estimate_json(&e));
    c.bench_function(&format!("pose/pnp_{PNP_N}/{ty}"), |b| {
        b.iter(|| solve_pnp(&cam, black_box(&world), black_box(&px), &mut scratch))
    });

    let (world, px) = load::<T>(&format!("ransac_{RANSAC_N}.csv"));
    let mut scratch = vec![Point2::origin(); px.len()];
    let mut mask = vec![false; px.len()];
    let config = RansacConfig::<T> {
        threshold: T::lit(THRESHOLD),
        confidence: T::lit(CONFIDENCE),
        seed: SEED,
        ..RansacConfig::default()
    }
    .check()
    .expect("RANSAC bench parameters");
    let (e, report) = solve_pnp_ransac(&cam, &world, &px, &mut scratch, &config, &mut mask)
        .expect("PnP RANSAC bench input");
    eprintln!(
        "pose/ransac_{RANSAC_N}/{ty}: {} inliers, {} samples",
        report.inliers, report.iterations
    );
    let mut v = estimate_json(&e);
    v["inliers"] = json!(report.inliers);
    v["mask"] = json!(mask);
    answers.record(&format!("ransac_{RANSAC_N}/{ty}"), v);
    c.bench_function(&format!("pose/ransac_{RANSAC_N}/{ty}"), |b| {
        b.iter(|| {
            solve_pnp_ransac(
                &cam,
                black_box(&world),
                black_box(&px),
                &mut scratch,
                &config,
                &mut mask,
            )
        })
    });
}

fn benches(c: &mut Criterion) {
    bench::sync_fixtures(&fixture_dir(), &generate());
    let mut answers = Answers::new(env!("CARGO_TARGET_TMPDIR"), "pose");
    bench_type::<f32>(c, "f32", &mut answers);
    bench_type::<f64>(c, "f64", &mut answers);
    answers.save();
}

criterion_group! {
    name = pose;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = benches
}
criterion_main!(pose);
