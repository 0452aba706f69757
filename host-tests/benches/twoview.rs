//! Two-view solvers on the host: the normalised 8-point (N = 64), 7-point and 5-point
//! minimal solvers, one F-RANSAC and one E-RANSAC run (N = 200, 50 % outliers, 1 px, fixed
//! seed), `recover_pose` and triangulation (N = 100), in f32 and f64 (the 5-point solver works
//! in f64 inside either way).
//!
//! The inputs are the files in `host-tests/data/fixtures/twoview_bench/` (rows `x1,y1,x2,y2`
//! in pixels of the camera `f = 600`, `c = (320, 240)`, and `truth.csv`: the camera, `R`, `t`
//! and `E`), which `host-tests/scripts/bench_twoview_opencv.py` times with OpenCV on the very
//! same numbers. They come from [`generate`] below; the bench checks that the files still
//! match it, and rewrites them with `CAMGEOM_WRITE_FIXTURES=1`:
//!
//! ```sh
//! CAMGEOM_WRITE_FIXTURES=1 cargo bench -p camgeom-host --bench twoview -- --test
//! cargo bench -p camgeom-host --bench twoview
//! python3 host-tests/scripts/bench_twoview_opencv.py --criterion target/criterion
//! ```

use std::hint::black_box;
use std::path::PathBuf;

use camgeom::Real;
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom::transform::Transform;
use camgeom::twoview::{
    Essential, RelativePose, View1, eight_point, find_essential, find_fundamental, five_point,
    recover_pose, seven_point, triangulate_dlt, triangulate_optimal,
};
use camgeom_host::points::read_csv;
use criterion::{Criterion, criterion_group, criterion_main};

const EIGHT_N: usize = 64;
const RANSAC_N: usize = 200;
const POSE_N: usize = 100;
/// Inlier threshold (Sampson distance, px) of both RANSAC runs.
pub const THRESHOLD: f64 = 1.0;
pub const CONFIDENCE: f64 = 0.999;
const SEED: u64 = 0x5eed_ca4e_0000_0001;
const NOISE: f64 = 0.5;
const COLUMNS: [&str; 4] = ["x1", "y1", "x2", "y2"];

fn fixture_dir() -> PathBuf {
    camgeom_host::data_dir()
        .join("fixtures")
        .join("twoview_bench")
}

fn camera() -> Intrinsics<f64> {
    Intrinsics::new(600.0, 600.0, 320.0, 240.0).expect("camera")
}

/// The ground truth: a sideways, slightly forward move with a small rotation.
fn pose() -> RelativePose<f64> {
    RelativePose::from_rodrigues(
        Vector3::new(0.04, -0.12, 0.03),
        Vector3::new(-0.8, 0.1, 0.2),
    )
    .expect("pose")
}

/// `(file name, text)` of every input: `eight_64.csv`, `seven.csv` (7 rows), `five.csv`
/// (5 rows), `ransac_200.csv` (every even row's second point replaced by a uniform one),
/// `pose_100.csv` (all inliers) with 0.5 px Gaussian noise on both points (the minimal
/// solvers' inputs exact), and `truth.csv` (`fx,fy,cx,cy,r11..r33,t1,t2,t3,e11..e33`).
fn generate() -> Vec<(String, String)> {
    let (k, pose) = (camera(), pose());
    let mut g = Pcg32::new(0x0054_5642_454e_4348);
    let csv = |rows: &[(Point2<f64>, Point2<f64>)]| {
        let mut s = String::from("x1,y1,x2,y2\n");
        for (a, b) in rows {
            s.push_str(&format!("{:?},{:?},{:?},{:?}\n", a.x, a.y, b.x, b.y));
        }
        s
    };
    let pairs = |g: &mut Pcg32, n: usize, noise: f64| -> Vec<(Point2<f64>, Point2<f64>)> {
        (0..n)
            .map(|_| {
                let x = Point3::new(
                    g.uniform(-2.0, 2.0),
                    g.uniform(-1.5, 1.5),
                    g.uniform(4.0, 8.0),
                );
                let c2 = pose.apply(&x);
                let px = |c: Point3<f64>| k.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
                let (a, b) = (px(x), px(c2));
                (
                    Point2::new(a.x + noise * g.normal(), a.y + noise * g.normal()),
                    Point2::new(b.x + noise * g.normal(), b.y + noise * g.normal()),
                )
            })
            .collect()
    };
    let mut out = vec![
        (
            format!("eight_{EIGHT_N}.csv"),
            csv(&pairs(&mut g, EIGHT_N, NOISE)),
        ),
        ("seven.csv".to_string(), csv(&pairs(&mut g, 7, 0.0))),
        ("five.csv".to_string(), csv(&pairs(&mut g, 5, 0.0))),
    ];
    let mut rows = pairs(&mut g, RANSAC_N, NOISE);
    for (i, r) in rows.iter_mut().enumerate() {
        if i % 2 == 0 {
            r.1 = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        }
    }
    out.push((format!("ransac_{RANSAC_N}.csv"), csv(&rows)));
    out.push((
        format!("pose_{POSE_N}.csv"),
        csv(&pairs(&mut g, POSE_N, NOISE)),
    ));
    let e = Essential::from_pose(&pose).expect("E");
    let r = pose.rotation();
    let t = pose.translation();
    let mut truth = String::from("fx,fy,cx,cy");
    for name in ["r", "t", "e"] {
        let n = if name == "t" { 3 } else { 9 };
        for i in 0..n {
            if name == "t" {
                truth.push_str(&format!(",t{}", i + 1));
            } else {
                truth.push_str(&format!(",{name}{}{}", i / 3 + 1, i % 3 + 1));
            }
        }
    }
    truth.push('\n');
    let mut vals: Vec<f64> = vec![k.fx(), k.fy(), k.cx(), k.cy()];
    vals.extend(r.matrix().transpose().iter()); // row-major
    vals.extend(t.iter());
    vals.extend(e.matrix().transpose().iter());
    let vals: Vec<String> = vals.iter().map(|v| format!("{v:?}")).collect();
    truth.push_str(&vals.join(","));
    truth.push('\n');
    out.push(("truth.csv".to_string(), truth));
    out
}

/// Writes the fixtures (`CAMGEOM_WRITE_FIXTURES=1`) or checks that they match [`generate`].
fn sync_fixtures() {
    let dir = fixture_dir();
    let write = std::env::var("CAMGEOM_WRITE_FIXTURES").is_ok_and(|v| v == "1");
    for (name, text) in generate() {
        let path = dir.join(&name);
        if write {
            std::fs::create_dir_all(&dir).expect("create the fixture directory");
            std::fs::write(&path, &text).expect("write a fixture");
        } else {
            let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                on_disk == text,
                "{} is missing or stale: rerun with CAMGEOM_WRITE_FIXTURES=1",
                path.display()
            );
        }
    }
}

/// `(x1, x2)` of a fixture, in `T`.
fn load<T: Real>(name: &str) -> (Vec<Point2<T>>, Vec<Point2<T>>) {
    let table = read_csv(fixture_dir().join(name), &COLUMNS).expect("fixture");
    let p = |x: f64, y: f64| Point2::new(T::lit(x), T::lit(y));
    table
        .rows
        .iter()
        .map(|r| (p(r[0], r[1]), p(r[2], r[3])))
        .unzip()
}

fn bench_type<T: Real>(c: &mut Criterion, ty: &str) {
    let k: Intrinsics<T> = camera().cast();
    let normalised = |v: &[Point2<T>]| -> Vec<Point2<T>> {
        v.iter()
            .map(|p| k.pixel_to_normalized(p).expect("normalise"))
            .collect()
    };
    let (a, b) = load::<T>(&format!("eight_{EIGHT_N}.csv"));
    c.bench_function(&format!("twoview/eight_point_{EIGHT_N}/{ty}"), |bn| {
        bn.iter(|| eight_point(black_box(&a), black_box(&b)))
    });
    let (a, b) = load::<T>("seven.csv");
    let (a7, b7): ([Point2<T>; 7], [Point2<T>; 7]) =
        (a.try_into().expect("7"), b.try_into().expect("7"));
    c.bench_function(&format!("twoview/seven_point/{ty}"), |bn| {
        bn.iter(|| seven_point(black_box(&a7), black_box(&b7)))
    });
    let (a, b) = load::<T>("five.csv");
    let (a5, b5): ([Point2<T>; 5], [Point2<T>; 5]) = (
        normalised(&a).try_into().expect("5"),
        normalised(&b).try_into().expect("5"),
    );
    let sols = five_point(&a5, &b5).expect("five-point bench input");
    eprintln!("twoview/five_point/{ty}: {} solutions", sols.len());
    c.bench_function(&format!("twoview/five_point/{ty}"), |bn| {
        bn.iter(|| five_point(black_box(&a5), black_box(&b5)))
    });
    let (a, b) = load::<T>(&format!("ransac_{RANSAC_N}.csv"));
    let config = RansacConfig::<T> {
        threshold: T::lit(THRESHOLD),
        confidence: T::lit(CONFIDENCE),
        seed: SEED,
        ..RansacConfig::default()
    };
    let mut mask = vec![false; a.len()];
    let (_, rf) = find_fundamental(&a, &b, &config, &mut mask).expect("F bench input");
    let (_, re) = find_essential(&k, &k, &a, &b, &config, &mut mask).expect("E bench input");
    eprintln!(
        "twoview/ransac_{RANSAC_N}/{ty}: F {} inliers, {} samples; E {} inliers, {} samples",
        rf.inliers, rf.iterations, re.inliers, re.iterations
    );
    c.bench_function(&format!("twoview/f_ransac_{RANSAC_N}/{ty}"), |bn| {
        bn.iter(|| find_fundamental(black_box(&a), black_box(&b), &config, &mut mask))
    });
    c.bench_function(&format!("twoview/e_ransac_{RANSAC_N}/{ty}"), |bn| {
        bn.iter(|| find_essential(&k, &k, black_box(&a), black_box(&b), &config, &mut mask))
    });
    let (a, b) = load::<T>(&format!("pose_{POSE_N}.csv"));
    let truth = pose();
    let e = Essential::<T>::from_matrix(&Essential::from_pose(&truth).expect("E").matrix().cast())
        .expect("E");
    let mut mask = vec![true; a.len()];
    c.bench_function(&format!("twoview/recover_pose_{POSE_N}/{ty}"), |bn| {
        bn.iter(|| {
            mask.iter_mut().for_each(|m| *m = true);
            recover_pose(
                &e,
                &k,
                &k,
                black_box(&a),
                black_box(&b),
                T::lit(50.0),
                &mut mask,
            )
        })
    });
    let (na, nb) = (normalised(&a), normalised(&b));
    let p1 = Transform::<View1, View1, T>::identity();
    let p2: RelativePose<T> =
        RelativePose::from_rodrigues(truth.rotation_vector().cast(), truth.translation().cast())
            .expect("pose");
    c.bench_function(&format!("twoview/triangulate_dlt_{POSE_N}/{ty}"), |bn| {
        bn.iter(|| {
            na.iter()
                .zip(&nb)
                .filter(|(x, y)| triangulate_dlt(&p1, &p2, black_box(x), black_box(y)).is_ok())
                .count()
        })
    });
    c.bench_function(
        &format!("twoview/triangulate_optimal_{POSE_N}/{ty}"),
        |bn| {
            bn.iter(|| {
                na.iter()
                    .zip(&nb)
                    .filter(|(x, y)| {
                        triangulate_optimal(&p1, &p2, black_box(x), black_box(y)).is_ok()
                    })
                    .count()
            })
        },
    );
}

fn benches(c: &mut Criterion) {
    sync_fixtures();
    bench_type::<f32>(c, "f32");
    bench_type::<f64>(c, "f64");
}

criterion_group! {
    name = twoview;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = benches
}
criterion_main!(twoview);
