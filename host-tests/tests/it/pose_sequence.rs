//! Planar pose accuracy against exact ground truth, side by side with OpenCV.
//!
//! The fixtures (`data/fixtures/pose_sequence/`, made by
//! `host-tests/scripts/make_pose_sequence.py`) are 8 frames of a real texture (the Oxford
//! graffiti image as a 0.25 x 0.20 m target) rendered by OpenCV's `warpPerspective` through
//! exact poses, with the features' image positions in three variants: `exact` projections,
//! `noisy` (Gaussian, σ = 0.5 px) and `measured` (cornerSubPix in the rendered frame), and
//! OpenCV's `solvePnP` (IPPE, ITERATIVE, SQPNP) on the same points. This test runs camgeom's
//! three planar paths on the same points — the homography decomposition, raw IPPE and the
//! refined `solve_planar` — and prints the table of BENCHMARKS.md ("Planar pose: synthetic
//! sequence and chessboard") with `--nocapture`.

use std::collections::BTreeMap;

use camgeom::homography::dlt;
use camgeom::nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use camgeom::pose::{PlanarConfig, ippe, pose_from_homography, solve_planar};
use camgeom::transform::Pose;
use camgeom_host::data_dir;

fn dir() -> std::path::PathBuf {
    data_dir().join("fixtures").join("pose_sequence")
}

fn rows(name: &str) -> Vec<Vec<String>> {
    std::fs::read_to_string(dir().join(name))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

/// The angle between two rotations from `|A - B|_F = 2√2 sin(θ/2)` (accurate near zero; the
/// script uses the same formula).
fn rot_deg(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (2.0 * ((a - b).norm() / (2.0 * 2f64.sqrt())).min(1.0).asin()).to_degrees()
}

/// Errors of one estimate: rotation (deg), translation (% of the true distance).
fn errors(est: &Pose<f64>, truth: &Pose<f64>) -> (f64, f64) {
    (
        rot_deg(est.rotation().matrix(), truth.rotation().matrix()),
        100.0 * (est.translation() - truth.translation()).norm() / truth.translation().norm(),
    )
}

#[derive(Default, Clone, Copy)]
struct Stat {
    n: usize,
    rot_sum: f64,
    rot_max: f64,
    t_sum: f64,
    t_max: f64,
}

impl Stat {
    fn add(&mut self, (r, t): (f64, f64)) {
        self.n += 1;
        self.rot_sum += r;
        self.rot_max = self.rot_max.max(r);
        self.t_sum += t;
        self.t_max = self.t_max.max(t);
    }
    fn rot_mean(&self) -> f64 {
        self.rot_sum / self.n as f64
    }
    fn t_mean(&self) -> f64 {
        self.t_sum / self.n as f64
    }
}

#[test]
fn planar_pose_accuracy_against_truth_and_opencv() {
    let spec = camgeom_host::load_camera(dir().join("camera.json")).unwrap();
    let cam = spec.camera;
    let k = cam.intrinsics;
    let truth: Vec<Pose<f64>> = rows("truth.csv")
        .iter()
        .map(|r| {
            let v: Vec<f64> = r[1..].iter().map(|s| s.parse().unwrap()).collect();
            Pose::from_rodrigues(
                Vector3::new(v[0], v[1], v[2]),
                Vector3::new(v[3], v[4], v[5]),
            )
            .unwrap()
        })
        .collect();
    assert_eq!(truth.len(), 8);
    type Points = (Vec<Point2<f64>>, Vec<Point2<f64>>);
    let mut sets: BTreeMap<(String, usize), Points> = BTreeMap::new();
    for r in rows("points.csv") {
        let f: usize = r[0].parse().unwrap();
        let v: Vec<f64> = r[2..].iter().map(|s| s.parse().unwrap()).collect();
        let e = sets.entry((r[1].clone(), f)).or_default();
        e.0.push(Point2::new(v[0], v[1]));
        e.1.push(Point2::new(v[2], v[3]));
    }
    let variants = ["exact", "noisy", "measured"];
    let methods = ["homography", "ippe", "refined", "refined_f32"];
    let mut ours: BTreeMap<(&str, &str), Stat> = BTreeMap::new();
    for variant in variants {
        for (f, truth) in truth.iter().enumerate() {
            let (model, pixels) = &sets[&(variant.to_string(), f)];
            // 1. The textbook decomposition of the DLT homography, H ~ K [r1 r2 t].
            let h = dlt(model, pixels).unwrap();
            let p = pose_from_homography(&k, &h).unwrap();
            ours.entry((variant, "homography"))
                .or_default()
                .add(errors(&p, truth));
            // 2. Raw IPPE (the better of its two solutions), no refinement.
            let normalized: Vec<Point2<f64>> = pixels
                .iter()
                .map(|u| cam.undistort_to_normalized(u).unwrap())
                .collect();
            let [(p, _), _] = ippe(model, &normalized).unwrap();
            ours.entry((variant, "ippe"))
                .or_default()
                .add(errors(&p, truth));
            // 3. IPPE refined by LM on the pixel error (what PlanarTarget runs), f64 and f32.
            let mut scratch = vec![Point2::origin(); model.len()];
            let sol =
                solve_planar(&cam, model, pixels, &mut scratch, &PlanarConfig::default()).unwrap();
            ours.entry((variant, "refined"))
                .or_default()
                .add(errors(&sol.best.pose, truth));
            let camf = cam.cast::<f32>();
            let mf: Vec<Point2<f32>> = model.iter().map(|p| p.cast()).collect();
            let pf: Vec<Point2<f32>> = pixels.iter().map(|p| p.cast()).collect();
            let mut sf = vec![Point2::origin(); model.len()];
            let solf = solve_planar(&camf, &mf, &pf, &mut sf, &PlanarConfig::default()).unwrap();
            let pose_f = Pose::new(
                Rotation3::from_matrix_unchecked(solf.best.pose.rotation().matrix().cast()),
                solf.best.pose.translation().cast(),
            )
            .unwrap();
            ours.entry((variant, "refined_f32"))
                .or_default()
                .add(errors(&pose_f, truth));
        }
    }
    let mut theirs: BTreeMap<(String, String), Stat> = BTreeMap::new();
    for r in rows("opencv.csv") {
        let (rd, tp): (f64, f64) = (r[9].parse().unwrap(), r[10].parse().unwrap());
        theirs
            .entry((r[1].clone(), r[2].clone()))
            .or_default()
            .add((rd, tp));
    }
    println!(
        "| points | method | rotation mean (deg) | rotation max (deg) | translation mean (%) | translation max (%) |"
    );
    println!("|---|---|---:|---:|---:|---:|");
    let show = |v: &str, m: &str, s: &Stat| {
        println!(
            "| {v} | {m} | {:.3e} | {:.3e} | {:.3e} | {:.3e} |",
            s.rot_mean(),
            s.rot_max,
            s.t_mean(),
            s.t_max
        );
    };
    for variant in variants {
        for m in methods {
            show(variant, &format!("camgeom {m}"), &ours[&(variant, m)]);
        }
        for m in ["ippe", "iterative", "sqpnp"] {
            let s = &theirs[&(variant.to_string(), m.to_string())];
            assert_eq!(s.n, 8);
            show(variant, &format!("OpenCV {m}"), s);
        }
    }
    for variant in variants {
        let refined = ours[&(variant, "refined")];
        let best_cv =
            ["ippe", "iterative", "sqpnp"].map(|m| theirs[&(variant.to_string(), m.to_string())]);
        let best_rot = best_cv.iter().map(Stat::rot_mean).fold(f64::MAX, f64::min);
        let best_t = best_cv.iter().map(Stat::t_mean).fold(f64::MAX, f64::min);
        if variant == "exact" {
            // Exact data: every camgeom path recovers the pose to rounding (the decomposition
            // and IPPE are closed forms, LM starts at the minimum).
            for m in ["homography", "ippe", "refined"] {
                let s = ours[&(variant, m)];
                assert!(s.rot_max < 1e-8 && s.t_max < 1e-8, "{m}");
            }
            // f32: 24-bit mantissas on 0.5 m poses and 600 px focal lengths.
            let s = ours[&(variant, "refined_f32")];
            assert!(s.rot_max < 1e-3 && s.t_max < 1e-3);
            continue;
        }
        // Noisy data: the refined pose minimises the same pixel error as OpenCV's ITERATIVE
        // (LM), the maximum-likelihood estimate under Gaussian pixel noise, and lands on the
        // same minimum: all four statistics agree to 1 % (observed: 3 digits).
        let it = theirs[&(variant.to_string(), "iterative".to_string())];
        let close = |a: f64, b: f64| (a - b).abs() <= 0.01 * b;
        assert!(
            close(refined.rot_mean(), it.rot_mean())
                && close(refined.rot_max, it.rot_max)
                && close(refined.t_mean(), it.t_mean())
                && close(refined.t_max, it.t_max),
            "{variant}: refined differs from OpenCV ITERATIVE"
        );
        // Against OpenCV's best method per statistic: SQPnP (object-space error) and raw IPPE
        // are sometimes closer to the truth on these 8 frames (by 2 % in rotation on `noisy`,
        // 11 % in translation on `measured`): with 8 poses the mean's own spread is larger
        // than these gaps, so they are not a property of the methods. The bounds (5 %
        // rotation, 15 % translation) keep a regression visible.
        assert!(
            refined.rot_mean() <= 1.05 * best_rot && refined.t_mean() <= 1.15 * best_t,
            "{variant}: {} deg {} % vs OpenCV best {best_rot} deg {best_t} %",
            refined.rot_mean(),
            refined.t_mean()
        );
        // Refinement pays: better rotation than the decomposition and raw IPPE.
        for m in ["homography", "ippe"] {
            assert!(refined.rot_mean() < ours[&(variant, m)].rot_mean(), "{m}");
        }
    }
}
