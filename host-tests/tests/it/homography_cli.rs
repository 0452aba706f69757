//! `camgeom homography`: the 4-point solver against OpenCV's `getPerspectiveTransform`, RANSAC on
//! correspondences with outliers, ORB features + matching + RANSAC on two images
//! (`--images`, against the Oxford graf ground truth), and input errors (status 2, one line
//! naming the camgeom error).

use std::process::Output;

use crate::common::{camgeom, scratch_file};
use camgeom::rng::Pcg32;
use serde_json::Value;

fn homography(file: &str, content: &str, extra: &[&str]) -> Output {
    let path = scratch_file(file, content);
    let mut args = vec!["homography", "--matches", path.to_str().unwrap()];
    args.extend_from_slice(extra);
    camgeom(&args)
}

fn json(out: &Output) -> Value {
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    assert!(out.stderr.is_empty(), "{out:?}");
    serde_json::from_slice(&out.stdout).unwrap()
}

fn matrix(v: &Value) -> [[f64; 3]; 3] {
    // Row-major, 9 numbers, h33 = 1.
    let flat = v["H"].as_array().unwrap();
    assert_eq!(flat.len(), 9);
    core::array::from_fn(|i| core::array::from_fn(|j| flat[3 * i + j].as_f64().unwrap()))
}

fn mask(v: &Value) -> Vec<bool> {
    v["inlier_mask"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_bool().unwrap())
        .collect()
}

fn apply(h: &[[f64; 3]; 3], x: f64, y: f64) -> (f64, f64) {
    let w = h[2][0] * x + h[2][1] * y + h[2][2];
    (
        (h[0][0] * x + h[0][1] * y + h[0][2]) / w,
        (h[1][0] * x + h[1][1] * y + h[1][2]) / w,
    )
}

fn assert_input_error(out: &Output, needle: &str) {
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(out.stdout.is_empty(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.ends_with('\n') && err.trim_end().lines().count() == 1,
        "not one line: {err:?}"
    );
    assert!(err.starts_with("camgeom: error: "), "{err}");
    assert!(err.contains(needle), "`{needle}` not in {err}");
}

const FOUR: &str = "x1,y1,x2,y2\n0,0,10,10\n100,0,110,12\n100,100,115,108\n0,100,9,111\n";

/// `cv2.getPerspectiveTransform` of [`FOUR`] (OpenCV 5.0.0, printed with 17 digits).
#[allow(clippy::excessive_precision)]
const OPENCV_FOUR: [[f64; 3]; 3] = [
    [1.0552644490236482, -1.5307624374448050e-02, 10.0],
    [2.6028848984397997e-02, 9.4453929938180747e-01, 10.0],
    [5.0240408203316652e-04, -5.8973604160533809e-04, 1.0],
];

#[test]
fn four_rows_use_the_exact_solver() {
    for f32 in [false, true] {
        let extra: &[&str] = if f32 { &["--f32"] } else { &[] };
        let v = json(&homography("four.csv", FOUR, extra));
        assert_eq!(v["method"], "four_point");
        assert_eq!(v["inliers"], 4);
        assert_eq!(mask(&v), vec![true; 4]);
        assert!(v.get("iterations").is_none());
        let h = matrix(&v);
        let tol = if f32 { 1e-5 } else { 1e-12 };
        for (r, o) in h.iter().zip(OPENCV_FOUR.iter()) {
            for (a, b) in r.iter().zip(o.iter()) {
                assert!((a - b).abs() <= tol * b.abs().max(1.0), "{h:?}");
            }
        }
        assert_eq!(h[2][2], 1.0);
    }
}

/// 60 correspondences of a perspective map, every third one replaced by a random point.
fn with_outliers() -> (String, Vec<bool>, [[f64; 3]; 3]) {
    let truth = [
        [0.92, -0.1, 25.0],
        [0.07, 1.04, -12.0],
        [1.2e-4, -1.6e-4, 1.0],
    ];
    let mut g = Pcg32::new(7);
    let mut csv = String::from("x1,y1,x2,y2\n");
    let mut inlier = Vec::new();
    for i in 0..60 {
        let (x, y) = (g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        let (mut u, mut v) = apply(&truth, x, y);
        u += 0.2 * g.normal();
        v += 0.2 * g.normal();
        let outlier = i % 3 == 0;
        if outlier {
            // At least 40 px away from the true match.
            u += g.uniform(40.0, 200.0)
                * if g.next_u32().is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                };
            v += g.uniform(40.0, 200.0);
        }
        inlier.push(!outlier);
        csv.push_str(&format!("{x:?},{y:?},{u:?},{v:?}\n"));
    }
    (csv, inlier, truth)
}

#[test]
fn ransac_separates_outliers() {
    let (csv, truth_mask, truth) = with_outliers();
    for f32 in [false, true] {
        let extra: &[&str] = if f32 { &["--f32"] } else { &[] };
        let v = json(&homography("outliers.csv", &csv, extra));
        assert_eq!(v["method"], "ransac");
        assert_eq!(mask(&v), truth_mask, "f32 = {f32}");
        assert_eq!(v["inliers"], 40);
        assert!(v["iterations"].as_u64().unwrap() >= 1);
        let h = matrix(&v);
        assert_eq!(h[2][2], 1.0);
        for (x, y) in [(0.0, 0.0), (639.0, 0.0), (639.0, 479.0), (0.0, 479.0)] {
            let (a, b) = (apply(&h, x, y), apply(&truth, x, y));
            assert!((a.0 - b.0).hypot(a.1 - b.1) < 0.5, "{a:?} {b:?}");
        }
    }
    // Deterministic for a seed; options are accepted.
    let args = ["--seed", "42", "--threshold", "2.5", "--confidence", "0.99"];
    let a = homography("outliers.csv", &csv, &args);
    let b = homography("outliers.csv", &csv, &args);
    assert_eq!(json(&a), json(&b));
    let few = homography("outliers.csv", &csv, &["--max-iters", "1"]);
    assert_eq!(json(&few)["iterations"], 1);
}

#[test]
fn input_errors_name_the_camgeom_error() {
    let three: String = FOUR.lines().take(4).map(|l| format!("{l}\n")).collect();
    assert_input_error(&homography("three.csv", &three, &[]), "too_few_points");
    assert_input_error(
        &homography("empty.csv", "x1,y1,x2,y2\n", &[]),
        "too_few_points",
    );
    let line: String = (0..8)
        .map(|i| format!("{i},{},{},3\n", 2 * i, i + 1))
        .collect();
    assert_input_error(&homography("line.csv", &line, &[]), "degenerate");
    let collinear4 = "0,0,0,0\n1,1,1,0\n2,2,1,1\n3,3,0,1\n";
    assert_input_error(&homography("line4.csv", collinear4, &[]), "degenerate");
    assert_input_error(
        &homography("nan.csv", "0,0,1,1\n1,0,nan,1\n", &[]),
        "not finite",
    );
    assert_input_error(
        &homography("short.csv", "0,0,1,1\n1,0,2\n", &[]),
        "expected 4",
    );
    // A parameter out of range: the message names it as camgeom's configuration spells it.
    let (csv, _, _) = with_outliers();
    assert_input_error(
        &homography("outliers.csv", &csv, &["--threshold", "0"]),
        "find_homography failed on 60 correspondences: invalid_parameter (parameter out of \
         range: ransac.threshold)",
    );
    assert_input_error(
        &homography("outliers.csv", &csv, &["--confidence", "1.5"]),
        "invalid_parameter (parameter out of range: ransac.confidence)",
    );
    assert_input_error(
        &homography("outliers.csv", &csv, &["--max-iters", "0"]),
        "invalid_parameter (parameter out of range: ransac.max_iterations)",
    );
}

fn graf(name: &str) -> String {
    let path = camgeom_host::data_dir().join("oxford-graf").join(name);
    path.to_str().unwrap().to_string()
}

/// `--images graf1.png graf3.png`: ORB + cross-check + RANSAC, the same pipeline as
/// `tests/it/features.rs::graf_homography_from_features_and_ransac`. The printed H maps a 40-px
/// grid of graf1 points (those whose true image lies inside graf3) within a mean of 2 px and a
/// max of 5 px of the ground truth H1to3p (measured 0.49 px mean, 1.35 px max over 311 points;
/// the features test 0.52 px, 1.4 px).
#[test]
fn images_give_the_graf_homography() {
    let (g1, g3) = (graf("graf1.png"), graf("graf3.png"));
    let v = json(&camgeom(&["homography", "--images", &g1, &g3]));
    assert_eq!(v["method"], "ransac");
    assert!(v["iterations"].as_u64().unwrap() >= 1);
    let m = v["matches"].as_u64().unwrap() as usize;
    let mask = mask(&v);
    assert_eq!(mask.len(), m);
    let inliers = v["inliers"].as_u64().unwrap() as usize;
    assert_eq!(inliers, mask.iter().filter(|b| **b).count());
    // Measured 87 inliers of 163 matches.
    assert!(inliers >= 40 && m >= 100, "{inliers} of {m}");
    let h = matrix(&v);
    assert_eq!(h[2][2], 1.0);
    let fs = camgeom_host::FileStorage::open(graf("H1to3p.xml")).unwrap();
    let t = fs.matrix("H13").unwrap().to_matrix3().unwrap();
    let truth: [[f64; 3]; 3] = core::array::from_fn(|i| core::array::from_fn(|j| t[(i, j)]));
    // graf1 and graf3 are 800 x 640.
    let (w, hgt) = (800.0, 640.0);
    let mut errors = Vec::new();
    for y in (0..640).step_by(40) {
        for x in (0..800).step_by(40) {
            let (x, y) = (f64::from(x), f64::from(y));
            let q = apply(&truth, x, y);
            if q.0 >= 0.0 && q.0 <= w - 1.0 && q.1 >= 0.0 && q.1 <= hgt - 1.0 {
                let p = apply(&h, x, y);
                errors.push((p.0 - q.0).hypot(p.1 - q.1));
            }
        }
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().cloned().fold(0.0, f64::max);
    assert!(errors.len() >= 100, "{}", errors.len());
    assert!(mean < 2.0 && max < 5.0, "mean {mean} px, max {max} px");
    // The same options as `--matches` reach RANSAC.
    let few = camgeom(&["homography", "--images", &g1, &g3, "--max-iters", "1"]);
    assert_eq!(json(&few)["iterations"], 1);
}

#[test]
fn image_input_errors() {
    let g1 = graf("graf1.png");
    let missing = graf("no-such-image.png");
    assert_input_error(
        &camgeom(&["homography", "--images", &g1, &missing]),
        "no-such-image.png",
    );
    // Not an image.
    assert_input_error(
        &camgeom(&["homography", "--images", &graf("H1to3p.xml"), &g1]),
        "H1to3p.xml",
    );
    // `--images` takes two files and excludes `--matches`.
    assert_input_error(&camgeom(&["homography", "--images", &g1]), "--images");
    assert_input_error(
        &camgeom(&["homography", "--images", &g1, &g1, "--matches", "x.csv"]),
        "cannot be used with",
    );
}
