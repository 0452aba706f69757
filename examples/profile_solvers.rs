//! The two-view and pose bench workloads (`host-tests/benches/{twoview,pose}.rs`, same fixture
//! files, same configurations) in a loop, for instruction counts under callgrind:
//!
//! ```sh
//! cargo build --release -p camgeom --example profile_solvers
//! valgrind --tool=callgrind target/release/examples/profile_solvers CASE TYPE [REPEATS]
//! ```
//!
//! `CASE`: `epnp_50`, `eight_64`, `seven`, `five`, `f_ransac_200`, `e_ransac_200`; `TYPE`:
//! `f32` or `f64`. Prints a checksum of the results so the work cannot be optimised away.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use camgeom::Real;
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Point2, Point3};
use camgeom::pose::epnp;
use camgeom::ransac::RansacConfig;
use camgeom::twoview::{eight_point, find_essential, find_fundamental, five_point, seven_point};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("host-tests/data/fixtures")
}

fn rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).expect("fixture");
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().expect("number"))
                .collect()
        })
        .collect()
}

fn pairs<T: Real>(name: &str) -> (Vec<Point2<T>>, Vec<Point2<T>>) {
    rows(&fixtures().join("twoview_bench").join(name))
        .iter()
        .map(|r| {
            (
                Point2::new(T::lit(r[0]), T::lit(r[1])),
                Point2::new(T::lit(r[2]), T::lit(r[3])),
            )
        })
        .unzip()
}

/// Prints the values (to the last bit) when `SHOW` is set: for comparing two builds.
fn show<T: Real>(v: &[T]) {
    if std::env::var_os("SHOW").is_some() {
        let v: Vec<String> = v.iter().map(|x| format!("{:?}", x.to_f64())).collect();
        println!("{}", v.join(" "));
    }
}

fn run<T: Real>(case: &str, repeats: usize) -> f64 {
    // The camera of both benches: f = 600, c = (320, 240).
    let k = Intrinsics::<T>::new(T::lit(600.0), T::lit(600.0), T::lit(320.0), T::lit(240.0))
        .expect("camera");
    let config = RansacConfig::<T> {
        threshold: T::lit(1.0),
        confidence: T::lit(0.999),
        seed: 0x5eed_ca4e_0000_0001,
        ..RansacConfig::default()
    }
    .check()
    .expect("RANSAC parameters");
    let mut sum = 0.0;
    match case {
        "epnp_50" => {
            let (world, px): (Vec<Point3<T>>, Vec<Point2<T>>) =
                rows(&fixtures().join("pose_bench/pnp_50.csv"))
                    .iter()
                    .map(|r| {
                        let l = T::lit;
                        (
                            Point3::new(l(r[0]), l(r[1]), l(r[2])),
                            Point2::new(l(r[3]), l(r[4])),
                        )
                    })
                    .unzip();
            let n: Vec<Point2<T>> = px
                .iter()
                .map(|u| k.pixel_to_normalized(u).expect("normalise"))
                .collect();
            for _ in 0..repeats {
                let (p, e) = epnp(black_box(&world), black_box(&n)).expect("epnp");
                sum += p.translation().x.to_f64() + e.to_f64();
                show(p.rotation().matrix().as_slice());
                show(p.translation().as_slice());
            }
        }
        "eight_64" => {
            let (a, b) = pairs::<T>("eight_64.csv");
            for _ in 0..repeats {
                let f = eight_point(black_box(&a), black_box(&b)).expect("8-point");
                sum += f.matrix()[(0, 0)].to_f64();
                show(f.matrix().as_slice());
            }
        }
        "seven" => {
            let (a, b) = pairs::<T>("seven.csv");
            let (a, b): ([Point2<T>; 7], [Point2<T>; 7]) =
                (a.try_into().expect("7"), b.try_into().expect("7"));
            for _ in 0..repeats {
                let f = seven_point(black_box(&a), black_box(&b)).expect("7-point");
                sum += f.len() as f64;
                f.iter().for_each(|f| show(f.matrix().as_slice()));
            }
        }
        "five" => {
            let (a, b) = pairs::<T>("five.csv");
            let n = |v: &[Point2<T>]| -> [Point2<T>; 5] {
                let v: Vec<Point2<T>> = v
                    .iter()
                    .map(|p| k.pixel_to_normalized(p).expect("normalise"))
                    .collect();
                v.try_into().expect("5")
            };
            let (a, b) = (n(&a), n(&b));
            for _ in 0..repeats {
                let e = five_point(black_box(&a), black_box(&b)).expect("5-point");
                sum += e.len() as f64;
                e.iter().for_each(|e| show(e.matrix().as_slice()));
            }
        }
        "f_ransac_200" | "e_ransac_200" => {
            let (a, b) = pairs::<T>("ransac_200.csv");
            let mut mask = vec![false; a.len()];
            for _ in 0..repeats {
                let r = if case == "f_ransac_200" {
                    find_fundamental(black_box(&a), black_box(&b), &config, &mut mask).map(
                        |(f, r)| {
                            show(f.matrix().as_slice());
                            r
                        },
                    )
                } else {
                    find_essential(&k, &k, black_box(&a), black_box(&b), &config, &mut mask).map(
                        |(e, r)| {
                            show(e.matrix().as_slice());
                            r
                        },
                    )
                };
                let r = r.expect("RANSAC");
                sum += r.inliers as f64 + f64::from(r.iterations) * 1e-3;
            }
        }
        _ => panic!("unknown case {case}"),
    }
    sum
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let case = args.get(1).map_or("five", String::as_str);
    let ty = args.get(2).map_or("f32", String::as_str);
    let repeats = args.get(3).and_then(|v| v.parse().ok()).unwrap_or(1);
    let sum = match ty {
        "f64" => run::<f64>(case, repeats),
        _ => run::<f32>(case, repeats),
    };
    println!("{case} {ty} x{repeats}: checksum {sum}");
}
