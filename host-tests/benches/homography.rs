//! Homography solvers on the host: the 4-point solver, the normalised DLT (N = 8, 64, 256) and
//! RANSAC (N = 200, 50 % outliers, threshold 3 px, fixed seed), in f32 and f64.
//!
//! The inputs are the CSV files in `host-tests/data/fixtures/homography_bench/` (rows
//! `x1,y1,x2,y2`, and `truth.csv`: the true `H`, row-major), which
//! `host-tests/scripts/bench_homography_opencv.py` and `scripts/peers.py` run OpenCV on. They
//! come from [`generate`] below; the bench checks that the files still match it, and rewrites
//! them with `CAMGEOM_WRITE_FIXTURES=1`. camgeom's estimates are left in
//! `target/tmp/peers/homography.json` for the peer harness's accuracy columns.
//!
//! ```sh
//! CAMGEOM_WRITE_FIXTURES=1 cargo bench -p camgeom-host --bench homography -- --test
//! cargo bench -p camgeom-host --bench homography
//! python3 host-tests/scripts/bench_homography_opencv.py --criterion target/criterion
//! ```

use std::hint::black_box;
use std::path::PathBuf;

use camgeom::Real;
use camgeom::homography::{Homography, dlt, find_homography};
use camgeom::nalgebra::{Matrix3, Point2, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom_host::bench::{self, Answers, pairs_csv, row_major};
use criterion::{Criterion, criterion_group, criterion_main};
use serde_json::json;

/// DLT sizes.
const DLT_SIZES: [usize; 3] = [8, 64, 256];
/// RANSAC problem: N correspondences, every other one an outlier.
const RANSAC_N: usize = 200;
const RANSAC_THRESHOLD: f64 = 3.0;
const RANSAC_SEED: u64 = 0x5eed_ca4e_0000_0001;

fn fixture_dir() -> PathBuf {
    bench::fixture_dir("homography_bench")
}

/// The ground truth of every bench input: a plane seen by two 640x480 cameras.
fn truth() -> Matrix3<f64> {
    Matrix3::new(0.93, -0.11, 31.0, 0.06, 1.04, -17.0, 1.4e-4, -1.9e-4, 1.0)
}

fn map(h: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
    let v = h * Vector3::new(p.x, p.y, 1.0);
    Point2::new(v.x / v.z, v.y / v.z)
}

/// `(file name, CSV text)` of every input: `four.csv` (4 exact correspondences),
/// `dlt_{8,64,256}.csv` (0.5 px Gaussian noise on the destination), `ransac_200.csv` (the same
/// noise, every even row replaced by a uniform random destination: 50 % outliers), and
/// `truth.csv` (`h11..h33`).
fn generate() -> Vec<(String, String)> {
    let h = truth();
    let mut g = Pcg32::new(0x4842_454e_4348);
    let csv = pairs_csv;
    let noisy = |g: &mut Pcg32, n: usize| -> Vec<(Point2<f64>, Point2<f64>)> {
        (0..n)
            .map(|_| {
                let p = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
                let q = map(&h, &p);
                (
                    p,
                    Point2::new(q.x + 0.5 * g.normal(), q.y + 0.5 * g.normal()),
                )
            })
            .collect()
    };
    let mut out = Vec::new();
    let corners = [(12.0, 30.0), (610.0, 25.0), (630.0, 470.0), (5.0, 460.0)];
    let four: Vec<_> = corners
        .iter()
        .map(|&(x, y)| {
            let p = Point2::new(x, y);
            (p, map(&h, &p))
        })
        .collect();
    out.push(("four.csv".to_string(), csv(&four)));
    for n in DLT_SIZES {
        out.push((format!("dlt_{n}.csv"), csv(&noisy(&mut g, n))));
    }
    let mut rows = noisy(&mut g, RANSAC_N);
    for (i, r) in rows.iter_mut().enumerate() {
        if i % 2 == 0 {
            r.1 = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        }
    }
    out.push((format!("ransac_{RANSAC_N}.csv"), csv(&rows)));
    let names: Vec<String> = (1..=9)
        .map(|i| format!("h{}{}", (i - 1) / 3 + 1, (i - 1) % 3 + 1))
        .collect();
    let vals: Vec<String> = row_major(&h).iter().map(|v| format!("{v:?}")).collect();
    out.push((
        "truth.csv".to_string(),
        format!("{}\n{}\n", names.join(","), vals.join(",")),
    ));
    out
}

/// `(src, dst)` of a fixture, in `T`.
fn load<T: Real>(name: &str) -> (Vec<Point2<T>>, Vec<Point2<T>>) {
    bench::load_pairs(&fixture_dir().join(name))
}

fn bench_type<T: Real>(c: &mut Criterion, ty: &str, answers: &mut Answers) {
    let h_json = |h: &Homography<T>| json!({ "H": row_major(h.matrix()) });
    let (s, d) = load::<T>("four.csv");
    let s4: [Point2<T>; 4] = s.try_into().expect("4 rows");
    let d4: [Point2<T>; 4] = d.try_into().expect("4 rows");
    let h = Homography::from_four_points(&s4, &d4).expect("4-point bench input");
    answers.record(&format!("four_point/{ty}"), h_json(&h));
    c.bench_function(&format!("homography/four_point/{ty}"), |b| {
        b.iter(|| Homography::from_four_points(black_box(&s4), black_box(&d4)))
    });
    for n in DLT_SIZES {
        let (s, d) = load::<T>(&format!("dlt_{n}.csv"));
        let h = dlt(&s, &d).expect("DLT bench input");
        answers.record(&format!("dlt_{n}/{ty}"), h_json(&h));
        c.bench_function(&format!("homography/dlt_{n}/{ty}"), |b| {
            b.iter(|| dlt(black_box(&s), black_box(&d)))
        });
    }
    let (s, d) = load::<T>(&format!("ransac_{RANSAC_N}.csv"));
    let config = RansacConfig::<T> {
        threshold: T::lit(RANSAC_THRESHOLD),
        seed: RANSAC_SEED,
        ..RansacConfig::default()
    }
    .check()
    .expect("RANSAC bench parameters");
    let mut mask = vec![false; s.len()];
    let (h, report) = find_homography(&s, &d, &config, &mut mask).expect("RANSAC bench input");
    eprintln!(
        "homography/ransac_{RANSAC_N}/{ty}: {} inliers, {} iterations",
        report.inliers, report.iterations
    );
    answers.record(
        &format!("ransac_{RANSAC_N}/{ty}"),
        json!({ "H": row_major(h.matrix()), "inliers": report.inliers, "mask": mask }),
    );
    c.bench_function(&format!("homography/ransac_{RANSAC_N}/{ty}"), |b| {
        b.iter(|| find_homography(black_box(&s), black_box(&d), &config, &mut mask))
    });
}

fn benches(c: &mut Criterion) {
    bench::sync_fixtures(&fixture_dir(), &generate());
    let mut answers = Answers::new(env!("CARGO_TARGET_TMPDIR"), "homography");
    bench_type::<f32>(c, "f32", &mut answers);
    bench_type::<f64>(c, "f64", &mut answers);
    answers.save();
}

criterion_group! {
    name = homography;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = benches
}
criterion_main!(homography);
