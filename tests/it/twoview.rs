//! Two-view geometry on synthetic scenes with exact ground truth: noise 0..2 px, outliers
//! 0..50 %, `f64` and `f32`.

use crate::common::{dir_err, rot_err};
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom::transform::Transform;
use camgeom::twoview::{
    Essential, RelativePose, View1, eight_point, find_essential, find_fundamental, recover_pose,
    refine_fundamental, triangulate_midpoint,
};

struct Scene {
    k: Intrinsics<f64>,
    pose: RelativePose<f64>,
    world: Vec<Point3<f64>>,
    x1: Vec<Point2<f64>>,
    x2: Vec<Point2<f64>>,
    inlier: Vec<bool>,
}

fn scene(seed: u64, n: usize, noise: f64, outliers: f64) -> Scene {
    let mut g = Pcg32::new(seed);
    let k = Intrinsics::new(600.0, 600.0, 320.0, 240.0).unwrap();
    let pose = RelativePose::from_rodrigues(
        Vector3::new(
            g.uniform(-0.2, 0.2),
            g.uniform(-0.3, 0.3),
            g.uniform(-0.1, 0.1),
        ),
        // A sideways baseline of 0.5..1 (depths 4..8): no near-pure rotation.
        Vector3::new(
            g.uniform(0.5, 1.0) * if g.uniform(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 },
            g.uniform(-0.3, 0.3),
            g.uniform(-0.3, 0.3),
        ),
    )
    .unwrap();
    let px = |c: Point3<f64>| k.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
    let (mut world, mut x1, mut x2, mut inlier) = (vec![], vec![], vec![], vec![]);
    while world.len() < n {
        let x = Point3::new(
            g.uniform(-2.0, 2.0),
            g.uniform(-1.5, 1.5),
            g.uniform(4.0, 8.0),
        );
        let c2 = pose.apply(&x);
        if c2.z < 1.0 {
            continue;
        }
        let mut a = px(x);
        let mut b = px(c2);
        a += Vector3::new(g.normal(), g.normal(), 0.0).xy() * noise;
        b += Vector3::new(g.normal(), g.normal(), 0.0).xy() * noise;
        let good = g.uniform(0.0, 1.0) >= outliers;
        if !good {
            b = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
        }
        world.push(x);
        x1.push(a);
        x2.push(b);
        inlier.push(good);
    }
    Scene {
        k,
        pose,
        world,
        x1,
        x2,
        inlier,
    }
}

#[test]
fn essential_and_pose_under_noise_and_outliers() {
    println!("noise outliers | rot err deg | t dir err deg | inliers (true) | supporting");
    for (seed, noise, outliers) in [
        (1, 0.0, 0.0),
        (2, 0.5, 0.0),
        (3, 1.0, 0.25),
        (4, 2.0, 0.25),
        (5, 0.5, 0.5),
        (6, 1.0, 0.5),
    ] {
        let s = scene(seed, 150, noise, outliers);
        let mut mask = vec![false; s.x1.len()];
        let cfg = RansacConfig {
            threshold: (2.0 * noise).max(1.0),
            confidence: 0.999,
            ..Default::default()
        }
        .check()
        .unwrap();
        let (e, rep) = find_essential(&s.k, &s.k, &s.x1, &s.x2, &cfg, &mut mask).unwrap();
        let sv = e.matrix().singular_values();
        assert!((sv.max() - 1.0).abs() < 1e-9 && sv.min() < 1e-9);
        let rp = recover_pose(&e, &s.k, &s.k, &s.x1, &s.x2, 50.0, &mut mask).unwrap();
        let (r, t) = (
            rot_err(&rp.pose, &s.pose),
            dir_err(&rp.pose.translation(), &s.pose.translation()),
        );
        let true_in = s.inlier.iter().filter(|m| **m).count();
        println!(
            "{noise:5.1} {outliers:5.2} | {r:.3} | {t:.3} | {} ({true_in}) | {} (runner-up {})",
            rep.inliers, rp.supporting, rp.runner_up
        );
        // Bounds from the conditioning of these scenes (60° field of view, depths 4-8, some
        // forward motion): the maximum-likelihood estimate started from the TRUE E on the true
        // inliers is off by as much (seed 2: 0.57 deg, 2.0 deg), and OpenCV's errors are of
        // the same size (tests/it/twoview_opencv.rs).
        assert!(r < 1e-6 + 2.0 * noise, "rotation {r}");
        assert!(t < 1e-6 + 10.0 * noise, "translation {t}");
        assert!(rp.supporting > rp.runner_up);
        // Triangulated inliers are in front and near the truth (scale from the true baseline).
        let scale = s.pose.translation().norm();
        let p1: Transform<View1, View1, f64> = Transform::identity();
        let mut errs = vec![];
        for (((a, b), x), m) in s.x1.iter().zip(&s.x2).zip(&s.world).zip(&mask) {
            if !m {
                continue;
            }
            let (na, nb) = (
                s.k.pixel_to_normalized(a).unwrap(),
                s.k.pixel_to_normalized(b).unwrap(),
            );
            if let Ok(tr) = triangulate_midpoint(&p1, &rp.pose, &na, &nb) {
                errs.push((tr.point.coords * scale - x.coords).norm() / x.coords.norm());
            }
        }
        errs.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert!(
            errs[errs.len() / 2] < 1e-8 + 0.3 * noise,
            "{}",
            errs[errs.len() / 2]
        );
    }
}

#[test]
fn fundamental_checks_and_f32() {
    for (seed, noise, outliers) in [
        (11, 0.0, 0.0),
        (12, 1.0, 0.0),
        (13, 0.5, 0.4),
        (14, 2.0, 0.3),
    ] {
        let s = scene(seed, 120, noise, outliers);
        let truth = Essential::from_pose(&s.pose)
            .unwrap()
            .to_fundamental(&s.k, &s.k)
            .unwrap();
        let mut mask = vec![false; s.x1.len()];
        let cfg = RansacConfig {
            threshold: (2.0 * noise).max(1.0),
            confidence: 0.999,
            ..Default::default()
        }
        .check()
        .unwrap();
        let (f, rep64) = find_fundamental(&s.x1, &s.x2, &cfg, &mut mask).unwrap();
        // OpenCV's checks: det F = 0 and the epipolar residual of the clean points.
        assert!(f.matrix().determinant().abs() < 1e-12);
        let px = |c: Point3<f64>| s.k.normalized_to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
        let mut worst = 0.0f64;
        for x in &s.world {
            let (a, b) = (px(*x), px(s.pose.apply(x)));
            worst = worst.max(f.sampson_sq(&a, &b).unwrap().sqrt());
            assert!(truth.residual(&a, &b).abs() < 1e-9);
        }
        println!(
            "noise {noise} outliers {outliers}: worst Sampson distance of clean pairs {worst:.3} px"
        );
        // Refinement does not increase the Sampson cost.
        let r = refine_fundamental(&f, &s.x1, &s.x2, Some(&mask), 10).unwrap();
        assert!(r.final_rms <= r.initial_rms + 1e-12);
        // f32: the same quality of epipolar geometry, up to f32 rounding.
        let a32: Vec<Point2<f32>> = s.x1.iter().map(|p| p.cast()).collect();
        let b32: Vec<Point2<f32>> = s.x2.iter().map(|p| p.cast()).collect();
        let mut m32 = vec![false; a32.len()];
        let cfg32 = RansacConfig::<f32> {
            threshold: cfg.config().threshold as f32,
            confidence: 0.999,
            ..Default::default()
        }
        .check()
        .unwrap();
        let (f32m, rep32) = find_fundamental(&a32, &b32, &cfg32, &mut m32).unwrap();
        let f64m = f32m.matrix().cast::<f64>();
        let rms = |f: &camgeom::nalgebra::Matrix3<f64>| {
            let s2: f64 = s
                .world
                .iter()
                .map(|x| {
                    camgeom::twoview::sampson_distance_sq(f, &px(*x), &px(s.pose.apply(x))).unwrap()
                })
                .sum();
            (s2 / s.world.len() as f64).sqrt()
        };
        let (r64, r32) = (rms(f.matrix()), rms(&f64m));
        assert!(r64 < 1e-6 + 1.2 * noise, "RMS {r64} px");
        println!(
            "  RMS Sampson distance of clean pairs: f64 {r64:.3} px, f32 {r32:.3} px \
             (inliers {} / {})",
            rep64.inliers, rep32.inliers
        );
        // f32 matches f64, outliers or not: the same samples give the same models (to
        // rounding), so both runs take the same RANSAC path. (Before the rank-2 projection
        // moved into normalised coordinates, f32 rejected or bent most 7-point models and
        // ended on a worse model under outliers: 5x the RMS at 2 px, 30 %.)
        assert!(r32 < 1e-3 + 1.1 * r64, "{r32} vs {r64}");
        assert!(rep32.inliers.abs_diff(rep64.inliers) <= 1);
        if outliers == 0.0 {
            let f8 = eight_point(&a32, &b32).unwrap();
            assert!(f8.matrix().determinant().abs() < 1e-6);
        }
    }
}

/// f32 RANSAC for `F` reaches the f64 model under many outliers (40-60 %): the MSAC cost of the
/// f32 model, evaluated in f64, is within 1 % of the f64 model's (the f32 rounding of the
/// Sampson residuals is about 1e-4 px², far below 1 % of costs of 60..1100 px²), with as many
/// inliers (±1 for a point at the threshold).
#[test]
fn fundamental_f32_ransac_matches_f64_under_outliers() {
    for (seed, noise, outliers) in [(13, 0.5, 0.4), (5, 1.0, 0.5), (6, 2.0, 0.5), (7, 1.0, 0.6)] {
        let s = scene(seed, 120, noise, outliers);
        let threshold = (2.0f64 * noise).max(1.0);
        let cfg = RansacConfig {
            threshold,
            confidence: 0.999,
            ..Default::default()
        }
        .check()
        .unwrap();
        let mut mask = vec![false; s.x1.len()];
        let (f, rep64) = find_fundamental(&s.x1, &s.x2, &cfg, &mut mask).unwrap();
        let a32: Vec<Point2<f32>> = s.x1.iter().map(|p| p.cast()).collect();
        let b32: Vec<Point2<f32>> = s.x2.iter().map(|p| p.cast()).collect();
        let cfg32 = RansacConfig::<f32> {
            threshold: threshold as f32,
            confidence: 0.999,
            ..Default::default()
        }
        .check()
        .unwrap();
        let mut m32 = vec![false; a32.len()];
        let (f32m, rep32) = find_fundamental(&a32, &b32, &cfg32, &mut m32).unwrap();
        let cost = |m: &camgeom::nalgebra::Matrix3<f64>| -> f64 {
            s.x1.iter()
                .zip(&s.x2)
                .map(|(a, b)| {
                    camgeom::twoview::sampson_distance_sq(m, a, b)
                        .map_or(threshold * threshold, |r| r.min(threshold * threshold))
                })
                .sum()
        };
        let (c64, c32) = (cost(f.matrix()), cost(&f32m.matrix().cast()));
        println!(
            "seed {seed}: cost f64 {c64:.2} ({} inliers, {} samples), f32 {c32:.2} ({} inliers, {} samples)",
            rep64.inliers, rep64.iterations, rep32.inliers, rep32.iterations
        );
        assert!(
            c32 <= 1.01 * c64,
            "seed {seed}: f32 cost {c32} vs f64 {c64}"
        );
        assert!(rep32.inliers.abs_diff(rep64.inliers) <= 1);
    }
}

#[test]
fn essential_f32_matches_f64() {
    let s = scene(21, 100, 0.5, 0.2);
    let k32 = s.k.cast::<f32>();
    let a32: Vec<Point2<f32>> = s.x1.iter().map(|p| p.cast()).collect();
    let b32: Vec<Point2<f32>> = s.x2.iter().map(|p| p.cast()).collect();
    let mut m = vec![false; a32.len()];
    let cfg = RansacConfig::<f32> {
        threshold: 1.0,
        confidence: 0.999,
        ..Default::default()
    }
    .check()
    .unwrap();
    let (e, _) = find_essential(&k32, &k32, &a32, &b32, &cfg, &mut m).unwrap();
    let rp = recover_pose(&e, &k32, &k32, &a32, &b32, 50.0, &mut m).unwrap();
    let pose64 = RelativePose::<f64>::from_rodrigues(
        rp.pose.rotation_vector().cast(),
        rp.pose.translation().cast(),
    )
    .unwrap();
    let r = rot_err(&pose64, &s.pose);
    let t = dir_err(&pose64.translation(), &s.pose.translation());
    println!("f32: rotation {r:.3} deg, translation {t:.3} deg");
    assert!(r < 0.5 && t < 2.0);
}

/// The f32 minimal and linear solvers on pixel coordinates: exact pairs give `F` whose Sampson
/// distance on 100 other exact pairs is at f32 rounding level (the pixel `F` has `σ₂/σ₁` of
/// about 1e-5, below `√ε` in f32: projecting it onto rank 2 again in pixels rejected it as
/// degenerate or bent it by whole pixels; 0.05 px is far above f32 rounding, 1e-3 px, and far
/// below that failure).
#[test]
fn f32_solvers_on_pixel_coordinates() {
    for seed in 31..37 {
        let s = scene(seed, 107, 0.0, 0.0);
        let a32: Vec<Point2<f32>> = s.x1.iter().map(|p| p.cast()).collect();
        let b32: Vec<Point2<f32>> = s.x2.iter().map(|p| p.cast()).collect();
        let worst = |f: &camgeom::nalgebra::Matrix3<f64>| -> f64 {
            s.x1[7..]
                .iter()
                .zip(&s.x2[7..])
                .map(|(a, b)| {
                    camgeom::twoview::sampson_distance_sq(f, a, b).map_or(f64::INFINITY, f64::sqrt)
                })
                .fold(0.0, f64::max)
        };
        let a7: [Point2<f32>; 7] = a32[..7].try_into().unwrap();
        let b7: [Point2<f32>; 7] = b32[..7].try_into().unwrap();
        let sols = camgeom::twoview::seven_point(&a7, &b7).expect("7-point in f32");
        let best = sols
            .iter()
            .map(|f| worst(&f.matrix().cast()))
            .fold(f64::INFINITY, f64::min);
        let f8 = eight_point(&a32, &b32).expect("8-point in f32");
        let w8 = worst(&f8.matrix().cast());
        println!("seed {seed}: 7-point {best:.2e} px, 8-point {w8:.2e} px");
        assert!(best < 0.05 && w8 < 0.05, "seed {seed}: {best} {w8}");
    }
}
