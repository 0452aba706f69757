//! kornia-3d, the Rust peer, on the very inputs of camgeom's `homography`, `pose` and `twoview`
//! benches (the CSV files under `host-tests/data/fixtures/*_bench/`), timed by criterion as
//! `kornia/<case>`, with its answers left in `target/tmp/peers/kornia.json` for
//! `host-tests/scripts/peers.py` to score beside camgeom's and OpenCV's.
//!
//! The settings follow camgeom's benches where kornia has them: RANSAC thresholds 3 px
//! (homography), 1 px (F, E), 2 px (PnP), 2000 / 1000 iterations, a fixed seed. kornia's
//! pose solvers are f32, its two-view ones f64.
//!
//! ```sh
//! CARGO_TARGET_DIR=target cargo bench --manifest-path host-tests/kornia-peer/Cargo.toml
//! ```

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use kornia_3d::pnp::{
    EPnPParams, LMRefineParams, PnPMethod, RansacParams as PnpRansacParams, epnp::solve_epnp,
    solve_pnp_ransac,
};
use kornia_3d::pose::{
    RansacParams, decompose_essential, essential_5pt, fundamental_8point, homography_4pt2d,
    homography_dlt, ransac_essential_5pt, ransac_fundamental, ransac_homography,
    triangulate_midpoint_known_pose, triangulate_n_view_linear,
};
use kornia_algebra::{Mat3AF32, Mat3F64, Vec2F32, Vec2F64, Vec3AF32, Vec3F64};
use serde_json::{Map, Value, json};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/fixtures")
}

/// The numbers of a CSV file with a header row (the bench inputs are well formed).
fn rows(path: PathBuf) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().expect("a number"))
                .collect()
        })
        .collect()
}

fn pairs(bench: &str, name: &str) -> (Vec<Vec2F64>, Vec<Vec2F64>) {
    rows(fixtures().join(bench).join(name))
        .iter()
        .map(|r| (Vec2F64::new(r[0], r[1]), Vec2F64::new(r[2], r[3])))
        .unzip()
}

/// Row-major entries of a (column-major) kornia matrix.
fn row_major(m: &Mat3F64) -> Vec<f64> {
    m.0.transpose().to_cols_array().to_vec()
}

fn row_major32(m: &Mat3AF32) -> Vec<f64> {
    m.0.transpose()
        .to_cols_array()
        .iter()
        .map(|v| f64::from(*v))
        .collect()
}

/// Column-major kornia matrix from row-major entries.
fn from_rows(v: &[f64]) -> Mat3F64 {
    Mat3F64::from_cols_array(&[v[0], v[3], v[6], v[1], v[4], v[7], v[2], v[5], v[8]])
}

fn homography(c: &mut Criterion, out: &mut Map<String, Value>) {
    let (a, b) = pairs("homography_bench", "four.csv");
    let a4: [[f64; 2]; 4] = std::array::from_fn(|i| [a[i].x, a[i].y]);
    let b4: [[f64; 2]; 4] = std::array::from_fn(|i| [b[i].x, b[i].y]);
    let mut h = [[0.0; 3]; 3];
    homography_4pt2d(&a4, &b4, &mut h).expect("4-point input");
    out.insert("homography/four_point".into(), json!({ "H": h.concat() }));
    c.bench_function("kornia/homography/four_point", |bn| {
        bn.iter(|| {
            let mut h = [[0.0; 3]; 3];
            homography_4pt2d(black_box(&a4), black_box(&b4), &mut h).map(|_| h)
        })
    });

    let (a, b) = pairs("homography_bench", "dlt_64.csv");
    let h = homography_dlt(&a, &b).expect("DLT input");
    out.insert("homography/dlt_64".into(), json!({ "H": row_major(&h) }));
    c.bench_function("kornia/homography/dlt_64", |bn| {
        bn.iter(|| homography_dlt(black_box(&a), black_box(&b)))
    });

    let (a, b) = pairs("homography_bench", "ransac_200.csv");
    let params = RansacParams {
        max_iterations: 2000,
        threshold: 3.0,
        min_inliers: 4,
        random_seed: Some(1),
        refit: true,
    };
    let r = ransac_homography(&a, &b, &params).expect("RANSAC input");
    out.insert(
        "homography/ransac_200".into(),
        json!({ "H": row_major(&r.model), "inliers": r.inlier_count }),
    );
    c.bench_function("kornia/homography/ransac_200", |bn| {
        bn.iter(|| ransac_homography(black_box(&a), black_box(&b), &params))
    });
}

fn pose(c: &mut Criterion, out: &mut Map<String, Value>) {
    // Rows of truth.csv are `case,fx,fy,cx,cy,...` (a name first): the camera of the first.
    let text = std::fs::read_to_string(fixtures().join("pose_bench/truth.csv")).expect("truth");
    let cam: Vec<f32> = text
        .lines()
        .nth(1)
        .expect("a case")
        .split(',')
        .skip(1)
        .take(4)
        .map(|v| v.parse().expect("a number"))
        .collect();
    let k = Mat3AF32::from_cols_array(&[cam[0], 0.0, 0.0, 0.0, cam[1], 0.0, cam[2], cam[3], 1.0]);
    let load = |name: &str| -> (Vec<Vec3AF32>, Vec<Vec2F32>) {
        rows(fixtures().join("pose_bench").join(name))
            .iter()
            .map(|r| {
                (
                    Vec3AF32::new(r[0] as f32, r[1] as f32, r[2] as f32),
                    Vec2F32::new(r[3] as f32, r[4] as f32),
                )
            })
            .unzip()
    };
    let pose_json = |r: &kornia_3d::pnp::PnPResult| {
        let t = [r.translation.x, r.translation.y, r.translation.z].map(f64::from);
        json!({ "R": row_major32(&r.rotation), "t": t })
    };

    let (w, u) = load("pnp_50.csv");
    let plain = EPnPParams::default();
    let r = solve_epnp(&w, &u, &k, None, &plain).expect("EPnP input");
    out.insert("pose/epnp_50".into(), pose_json(&r));
    c.bench_function("kornia/pose/epnp_50", |bn| {
        bn.iter(|| solve_epnp(black_box(&w), black_box(&u), &k, None, &plain))
    });
    let refined = EPnPParams {
        refine_lm: Some(LMRefineParams::default()),
        ..EPnPParams::default()
    };
    let r = solve_epnp(&w, &u, &k, None, &refined).expect("EPnP input");
    out.insert("pose/pnp_50".into(), pose_json(&r));
    c.bench_function("kornia/pose/pnp_50", |bn| {
        bn.iter(|| solve_epnp(black_box(&w), black_box(&u), &k, None, &refined))
    });

    let (w, u) = load("ransac_100.csv");
    let params = PnpRansacParams {
        max_iterations: 1000,
        reproj_threshold_px: 2.0,
        confidence: 0.999,
        random_seed: Some(1),
        refine: true,
    };
    let r =
        solve_pnp_ransac(&w, &u, &k, None, PnPMethod::EPnPDefault, &params).expect("RANSAC input");
    let mut v = pose_json(&r.pose);
    v["inliers"] = json!(r.inliers.len());
    out.insert("pose/ransac_100".into(), v);
    c.bench_function("kornia/pose/ransac_100", |bn| {
        bn.iter(|| {
            solve_pnp_ransac(
                black_box(&w),
                black_box(&u),
                &k,
                None,
                PnPMethod::EPnPDefault,
                &params,
            )
        })
    });
}

fn twoview(c: &mut Criterion, out: &mut Map<String, Value>) {
    let t = &rows(fixtures().join("twoview_bench/truth.csv"))[0];
    let k = Mat3F64::from_cols_array(&[t[0], 0.0, 0.0, 0.0, t[1], 0.0, t[2], t[3], 1.0]);
    let kinv = Mat3F64::from(k.0.inverse());
    let norm = |p: &Vec2F64| {
        let v = kinv.0 * glam::DVec3::new(p.x, p.y, 1.0);
        Vec2F64::new(v.x / v.z, v.y / v.z)
    };

    let (a, b) = pairs("twoview_bench", "eight_64.csv");
    let f = fundamental_8point(&a, &b).expect("8-point input");
    out.insert(
        "twoview/eight_point_64".into(),
        json!({ "F": row_major(&f) }),
    );
    c.bench_function("kornia/twoview/eight_point_64", |bn| {
        bn.iter(|| fundamental_8point(black_box(&a), black_box(&b)))
    });

    let (a, b) = pairs("twoview_bench", "five.csv");
    let a5: [Vec2F64; 5] = std::array::from_fn(|i| norm(&a[i]));
    let b5: [Vec2F64; 5] = std::array::from_fn(|i| norm(&b[i]));
    let es: Vec<Vec<f64>> = essential_5pt(&a5, &b5).iter().map(row_major).collect();
    out.insert("twoview/five_point".into(), json!({ "E": es }));
    c.bench_function("kornia/twoview/five_point", |bn| {
        bn.iter(|| essential_5pt(black_box(&a5), black_box(&b5)))
    });

    let (a, b) = pairs("twoview_bench", "ransac_200.csv");
    let params = RansacParams {
        max_iterations: 2000,
        threshold: 1.0,
        min_inliers: 8,
        random_seed: Some(1),
        refit: false,
    };
    let r = ransac_fundamental(&a, &b, &params).expect("F RANSAC input");
    out.insert(
        "twoview/f_ransac_200".into(),
        json!({ "F": row_major(&r.model), "inliers": r.inlier_count }),
    );
    c.bench_function("kornia/twoview/f_ransac_200", |bn| {
        bn.iter(|| ransac_fundamental(black_box(&a), black_box(&b), &params))
    });
    let r = ransac_essential_5pt(&a, &b, &k, &k, &params).expect("E RANSAC input");
    // kornia-3d has no public recoverPose: its four candidates, the one that puts most
    // inliers in front of both cameras (midpoint triangulation, as its own pipeline does).
    let (rot, tr, front) = decompose_essential(&r.model)
        .iter()
        .map(|(rot, tr)| {
            let n = a
                .iter()
                .zip(&b)
                .zip(&r.inliers)
                .filter(|(_, m)| **m)
                .filter(|((p, q), _)| {
                    let (p, q) = (norm(p), norm(q));
                    let ray1 = Vec3F64::new(p.x, p.y, 1.0);
                    let ray2 = Vec3F64::new(q.x, q.y, 1.0);
                    triangulate_midpoint_known_pose(&ray1, &ray2, rot, tr).is_some_and(|(x, _)| {
                        let c2 = rot.0 * glam::DVec3::new(x.x, x.y, x.z)
                            + glam::DVec3::new(tr.x, tr.y, tr.z);
                        x.z > 0.0 && c2.z > 0.0
                    })
                })
                .count();
            (*rot, *tr, n)
        })
        .max_by_key(|c| c.2)
        .expect("four candidates");
    out.insert(
        "twoview/e_ransac_200".into(),
        json!({
            "E": row_major(&r.model),
            "R": row_major(&rot),
            "t": [tr.x, tr.y, tr.z],
            "inliers": r.inlier_count,
            "supporting": front,
        }),
    );
    c.bench_function("kornia/twoview/e_ransac_200", |bn| {
        bn.iter(|| ransac_essential_5pt(black_box(&a), black_box(&b), &k, &k, &params))
    });

    // Triangulation with the true pose, normalised coordinates, P1 = [I | 0], P2 = [R | t].
    let (a, b) = pairs("twoview_bench", "pose_100.csv");
    let r_true = from_rows(&t[4..13]);
    let rt = r_true.0.transpose().to_cols_array(); // row-major R
    let p1 = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let p2 = [
        rt[0], rt[1], rt[2], t[13], rt[3], rt[4], rt[5], t[14], rt[6], rt[7], rt[8], t[15],
    ];
    let (na, nb): (Vec<Vec2F64>, Vec<Vec2F64>) =
        a.iter().zip(&b).map(|(p, q)| (norm(p), norm(q))).unzip();
    let tri = |na: &[Vec2F64], nb: &[Vec2F64]| -> Vec<Option<Vec3F64>> {
        na.iter()
            .zip(nb)
            .map(|(p, q)| triangulate_n_view_linear(&[*p, *q], &[p1, p2]))
            .collect()
    };
    let pts: Vec<Option<[f64; 3]>> = tri(&na, &nb)
        .iter()
        .map(|p| p.map(|p| [p.x, p.y, p.z]))
        .collect();
    out.insert("twoview/triangulate_100".into(), json!({ "points": pts }));
    c.bench_function("kornia/twoview/triangulate_100", |bn| {
        bn.iter(|| tri(black_box(&na), black_box(&nb)))
    });
}

fn benches(c: &mut Criterion) {
    let mut out = Map::new();
    homography(c, &mut out);
    pose(c, &mut out);
    twoview(c, &mut out);
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("peers");
    std::fs::create_dir_all(&dir).expect("answers directory");
    let text = serde_json::to_string_pretty(&Value::Object(out)).expect("JSON");
    std::fs::write(dir.join("kornia.json"), text + "\n").expect("write the answers");
}

criterion_group! {
    name = kornia;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = benches
}
criterion_main!(kornia);
