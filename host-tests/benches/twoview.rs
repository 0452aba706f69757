//! Two-view solvers on the host: the normalised 8-point (N = 64), 7-point and 5-point
//! minimal solvers, one F-RANSAC and one E-RANSAC run (N = 200, 50 % outliers, 1 px, fixed
//! seed), `recover_pose` and triangulation (N = 100), in f32 and f64 (the 5-point solver works
//! in f64 inside either way).
//!
//! The inputs are the files in `host-tests/data/fixtures/twoview_bench/` (rows `x1,y1,x2,y2`
//! in pixels of the camera `f = 600`, `c = (320, 240)`; `truth.csv`: the camera, `R`, `t` and
//! `E`; `pose_100_points.csv`: the 3D points behind `pose_100.csv`, view-1 camera frame), which
//! `host-tests/scripts/bench_twoview_opencv.py` and `scripts/peers.py` run OpenCV on. They come
//! from [`generate`] below; the bench checks that the files still match it, and rewrites them
//! with `CAMGEOM_WRITE_FIXTURES=1`. camgeom's answers are left in
//! `target/tmp/peers/twoview.json` for the peer harness's accuracy columns:
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
use camgeom_host::bench::{self, Answers, pairs_csv, row_major};
use criterion::{Criterion, criterion_group, criterion_main};
use serde_json::json;

const EIGHT_N: usize = 64;
const RANSAC_N: usize = 200;
const POSE_N: usize = 100;
/// Inlier threshold (Sampson distance, px) of both RANSAC runs.
pub const THRESHOLD: f64 = 1.0;
pub const CONFIDENCE: f64 = 0.999;
const SEED: u64 = 0x5eed_ca4e_0000_0001;
const NOISE: f64 = 0.5;

fn fixture_dir() -> PathBuf {
    bench::fixture_dir("twoview_bench")
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

/// Pixel pairs with their 3D points (view-1 camera frame).
type Scene = Vec<((Point2<f64>, Point2<f64>), Point3<f64>)>;

/// `(file name, text)` of every input: `eight_64.csv`, `seven.csv` (7 rows), `five.csv`
/// (5 rows), `ransac_200.csv` (every even row's second point replaced by a uniform one),
/// `pose_100.csv` (all inliers) with 0.5 px Gaussian noise on both points (the minimal
/// solvers' inputs exact), `pose_100_points.csv` (`X,Y,Z`) and `truth.csv`
/// (`fx,fy,cx,cy,r11..r33,t1,t2,t3,e11..e33`).
fn generate() -> Vec<(String, String)> {
    let (k, pose) = (camera(), pose());
    let mut g = Pcg32::new(0x0054_5642_454e_4348);
    let csv = |scene: &Scene| pairs_csv(&scene.iter().map(|s| s.0).collect::<Vec<_>>());
    let pairs = |g: &mut Pcg32, n: usize, noise: f64| -> Scene {
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
                    (
                        Point2::new(a.x + noise * g.normal(), a.y + noise * g.normal()),
                        Point2::new(b.x + noise * g.normal(), b.y + noise * g.normal()),
                    ),
                    x,
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
            r.0.1 = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        }
    }
    out.push((format!("ransac_{RANSAC_N}.csv"), csv(&rows)));
    let scene = pairs(&mut g, POSE_N, NOISE);
    out.push((format!("pose_{POSE_N}.csv"), csv(&scene)));
    let mut world = String::from("X,Y,Z\n");
    for (_, x) in &scene {
        world.push_str(&format!("{:?},{:?},{:?}\n", x.x, x.y, x.z));
    }
    out.push((format!("pose_{POSE_N}_points.csv"), world));
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

/// `(x1, x2)` of a fixture, in `T`.
fn load<T: Real>(name: &str) -> (Vec<Point2<T>>, Vec<Point2<T>>) {
    bench::load_pairs(&fixture_dir().join(name))
}

fn bench_type<T: Real>(c: &mut Criterion, ty: &str, answers: &mut Answers) {
    let k: Intrinsics<T> = camera().cast();
    let normalised = |v: &[Point2<T>]| -> Vec<Point2<T>> {
        v.iter()
            .map(|p| k.pixel_to_normalized(p).expect("normalise"))
            .collect()
    };
    let (a, b) = load::<T>(&format!("eight_{EIGHT_N}.csv"));
    let f = eight_point(&a, &b).expect("8-point bench input");
    answers.record(
        &format!("eight_point_{EIGHT_N}/{ty}"),
        json!({ "F": row_major(f.matrix()) }),
    );
    c.bench_function(&format!("twoview/eight_point_{EIGHT_N}/{ty}"), |bn| {
        bn.iter(|| eight_point(black_box(&a), black_box(&b)))
    });
    let (a, b) = load::<T>("seven.csv");
    let (a7, b7): ([Point2<T>; 7], [Point2<T>; 7]) =
        (a.try_into().expect("7"), b.try_into().expect("7"));
    let sols = seven_point(&a7, &b7).expect("7-point bench input");
    let fs: Vec<Vec<f64>> = sols.iter().map(|f| row_major(f.matrix())).collect();
    answers.record(&format!("seven_point/{ty}"), json!({ "F": fs }));
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
    let es: Vec<Vec<f64>> = sols.iter().map(|e| row_major(e.matrix())).collect();
    answers.record(&format!("five_point/{ty}"), json!({ "E": es }));
    c.bench_function(&format!("twoview/five_point/{ty}"), |bn| {
        bn.iter(|| five_point(black_box(&a5), black_box(&b5)))
    });
    let (a, b) = load::<T>(&format!("ransac_{RANSAC_N}.csv"));
    let config = RansacConfig::<T> {
        threshold: T::lit(THRESHOLD),
        confidence: T::lit(CONFIDENCE),
        seed: SEED,
        ..RansacConfig::default()
    }
    .check()
    .expect("RANSAC bench parameters");
    let mut mask = vec![false; a.len()];
    let (f, rf) = find_fundamental(&a, &b, &config, &mut mask).expect("F bench input");
    answers.record(
        &format!("f_ransac_{RANSAC_N}/{ty}"),
        json!({ "F": row_major(f.matrix()), "inliers": rf.inliers, "mask": mask }),
    );
    let (e, re) = find_essential(&k, &k, &a, &b, &config, &mut mask).expect("E bench input");
    // The pose the E-RANSAC run leads to, through the same cheirality test OpenCV's
    // `recoverPose` applies after `findEssentialMat`.
    let rp = recover_pose(&e, &k, &k, &a, &b, T::lit(50.0), &mut mask.clone()).expect("pose");
    answers.record(
        &format!("e_ransac_{RANSAC_N}/{ty}"),
        json!({
            "E": row_major(e.matrix()),
            "R": row_major(rp.pose.rotation().matrix()),
            "t": rp.pose.translation().iter().map(|v| v.to_f64()).collect::<Vec<_>>(),
            "inliers": re.inliers,
            "mask": mask,
        }),
    );
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
    let rp = recover_pose(&e, &k, &k, &a, &b, T::lit(50.0), &mut mask).expect("pose");
    answers.record(
        &format!("recover_pose_{POSE_N}/{ty}"),
        json!({
            "R": row_major(rp.pose.rotation().matrix()),
            "t": rp.pose.translation().iter().map(|v| v.to_f64()).collect::<Vec<_>>(),
            "supporting": rp.supporting,
        }),
    );
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
    for (name, points) in [
        (
            "dlt",
            na.iter()
                .zip(&nb)
                .map(|(x, y)| triangulate_dlt(&p1, &p2, x, y).map(|t| t.point))
                .collect::<Vec<_>>(),
        ),
        (
            "optimal",
            na.iter()
                .zip(&nb)
                .map(|(x, y)| triangulate_optimal(&p1, &p2, x, y).map(|t| t.point))
                .collect(),
        ),
    ] {
        // A point that fails (behind a camera, at infinity) is `null`.
        let xyz: Vec<Option<[f64; 3]>> = points
            .iter()
            .map(|p| {
                p.as_ref()
                    .ok()
                    .map(|p| [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()])
            })
            .collect();
        answers.record(
            &format!("triangulate_{name}_{POSE_N}/{ty}"),
            json!({ "points": xyz }),
        );
    }
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
    bench::sync_fixtures(&fixture_dir(), &generate());
    let mut answers = Answers::new(env!("CARGO_TARGET_TMPDIR"), "twoview");
    bench_type::<f32>(c, "f32", &mut answers);
    bench_type::<f64>(c, "f64", &mut answers);
    answers.save();
}

criterion_group! {
    name = twoview;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = benches
}
criterion_main!(twoview);
