//! E-RANSAC in f32 against f64 on identical draws of the two-view noise study's scene
//! (`host-tests/scripts/twoview_study.py`, `scripts/fixtures/twoview.py`: `K` with
//! `f = 520`, `c = (320, 240)`, 80 points in a box 4..9 in front of camera 1 and visible in
//! both 640x480 images, `R = exp(0.05, -0.22, 0.04)`, `t = (-0.9, 0.08, 0.15)`, 30 % of the
//! second-image points replaced by uniform pixels, Gaussian noise on both images), drawn here
//! with camgeom's PCG32 instead of numpy (same distributions, other numbers). The f32 run gets
//! the f64 pixels rounded to f32. Both run `find_essential` (1 px, p = 0.999, the default
//! seed) then `recover_pose`, as the CLI's `twoview` command does.
//!
//! Also the minimal solver alone: on random 5-subsets of the true inliers (noisy, so every
//! subset is an exact problem of its own), how often `five_point::<f32>` returns nothing
//! while `five_point::<f64>` returns a solution, and how often it misses the f64 solution
//! nearest the true `E` (by more than 1e-3, max entry, up to sign).
//!
//! ```sh
//! cargo run --release -p camgeom --example twoview_precision [DRAWS]
//! ```

use camgeom::Real;
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Matrix3, Point2, Point3, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::rng::Pcg32;
use camgeom::twoview::{Essential, RelativePose, find_essential, five_point, recover_pose};

const N: usize = 80;
const OUTLIERS: usize = 24; // round(0.3 N)
const SUBSETS: usize = 20;

/// Per type: rotation errors, translation errors, gross failures, inliers summed, runs failed.
type Outcomes = (Vec<f64>, Vec<f64>, usize, usize, usize);

fn truth() -> RelativePose<f64> {
    RelativePose::from_rodrigues(
        Vector3::new(0.05, -0.22, 0.04),
        Vector3::new(-0.9, 0.08, 0.15),
    )
    .expect("pose")
}

fn camera() -> Intrinsics<f64> {
    Intrinsics::new(520.0, 520.0, 320.0, 240.0).expect("camera")
}

/// `(world points, clean pixels in view 1, in view 2)`.
fn scene(g: &mut Pcg32) -> Vec<(Point2<f64>, Point2<f64>)> {
    let (k, pose) = (camera(), truth());
    let inside = |u: &Point2<f64>| (0.0..640.0).contains(&u.x) && (0.0..480.0).contains(&u.y);
    let mut out = Vec::new();
    while out.len() < N {
        let x = Point3::new(
            g.uniform(-2.0, 2.0),
            g.uniform(-1.5, 1.5),
            g.uniform(4.0, 9.0),
        );
        let c2 = pose.apply(&x);
        let u1 = k.normalized_to_pixel(&Point2::new(x.x / x.z, x.y / x.z));
        let u2 = k.normalized_to_pixel(&Point2::new(c2.x / c2.z, c2.y / c2.z));
        if c2.z > 0.5 && inside(&u1) && inside(&u2) {
            out.push((u1, u2));
        }
    }
    out
}

/// Rotation angle of `R_est R_trueᵀ` and angle between the translation directions, degrees.
fn errors<T: Real>(p: &RelativePose<T>) -> (f64, f64) {
    let t = truth();
    let r: Matrix3<f64> = p.rotation().matrix().map(|v| v.to_f64());
    let c = (((r * t.rotation().matrix().transpose()).trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    let te: Vector3<f64> = p.translation().map(|v| v.to_f64()).normalize();
    let tt = t.translation().normalize();
    (
        c.acos().to_degrees(),
        te.dot(&tt).clamp(-1.0, 1.0).acos().to_degrees(),
    )
}

fn run<T: Real>(x1: &[Point2<f64>], x2: &[Point2<f64>]) -> Option<((f64, f64), usize)> {
    let k: Intrinsics<T> = camera().cast();
    let a: Vec<Point2<T>> = x1.iter().map(|p| p.map(T::lit)).collect();
    let b: Vec<Point2<T>> = x2.iter().map(|p| p.map(T::lit)).collect();
    let config = RansacConfig::<T> {
        threshold: T::lit(1.0),
        confidence: T::lit(0.999),
        ..RansacConfig::default()
    }
    .check()
    .ok()?;
    let mut mask = vec![false; a.len()];
    let (e, report) = find_essential(&k, &k, &a, &b, &config, &mut mask).ok()?;
    let rp = recover_pose(&e, &k, &k, &a, &b, T::lit(50.0), &mut mask).ok()?;
    Some((errors(&rp.pose), report.inliers))
}

fn stats(v: &mut [f64]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    format!(
        "{:.3} / {:.3} / {:.3} / {:.2}",
        q(0.5),
        mean,
        q(0.9),
        q(1.0)
    )
}

fn main() {
    let draws: usize = std::env::args()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let mut g = Pcg32::new(20250612);
    let clean = scene(&mut g);
    let (k, e_true) = (camera(), Essential::from_pose(&truth()).expect("E"));
    println!("E-RANSAC + recover_pose, {draws} draws per level, N = {N}, 30 % outliers, 1 px\n");
    println!(
        "| noise px | type | rotation error ° median / mean / p90 / max | translation-direction error ° median / mean / p90 / max | > 10° | inliers mean | failed |"
    );
    println!("|---:|---|---|---|---:|---:|---:|");
    let mut minimal = Vec::new();
    for noise in [0.0, 0.5, 1.0, 2.0] {
        let mut res: [Outcomes; 2] = Default::default();
        let (mut none, mut missed, mut solved64) = (0usize, 0usize, 0usize);
        for _ in 0..draws {
            let mut x1: Vec<Point2<f64>> = Vec::new();
            let mut x2: Vec<Point2<f64>> = Vec::new();
            for (a, b) in &clean {
                x1.push(Point2::new(
                    a.x + noise * g.normal(),
                    a.y + noise * g.normal(),
                ));
                x2.push(Point2::new(
                    b.x + noise * g.normal(),
                    b.y + noise * g.normal(),
                ));
            }
            // Outliers: OUTLIERS distinct indices (partial Fisher-Yates).
            let mut idx: Vec<usize> = (0..N).collect();
            for i in 0..OUTLIERS {
                let j = i + g.below((N - i) as u32) as usize;
                idx.swap(i, j);
                x2[idx[i]] = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
            }
            let inliers: Vec<usize> = idx[OUTLIERS..].to_vec();
            for (slot, out) in res
                .iter_mut()
                .zip([run::<f32>(&x1, &x2), run::<f64>(&x1, &x2)])
            {
                match out {
                    Some(((r, t), n)) => {
                        slot.0.push(r);
                        slot.1.push(t);
                        slot.2 += usize::from(r > 10.0 || t > 10.0);
                        slot.3 += n;
                    }
                    None => slot.4 += 1,
                }
            }
            // Minimal solves on random inlier subsets.
            for _ in 0..SUBSETS {
                let mut pick = inliers.clone();
                for i in 0..5 {
                    let j = i + g.below((pick.len() - i) as u32) as usize;
                    pick.swap(i, j);
                }
                let n = |p: &Point2<f64>| k.pixel_to_normalized(p).expect("normalise");
                let a: [Point2<f64>; 5] = core::array::from_fn(|i| n(&x1[pick[i]]));
                let b: [Point2<f64>; 5] = core::array::from_fn(|i| n(&x2[pick[i]]));
                let Ok(s64) = five_point(&a, &b) else {
                    continue;
                };
                solved64 += 1;
                let d = |m: &Matrix3<f64>, e: &Matrix3<f64>| (m - e).amax().min((m + e).amax());
                let Some(best) = s64.iter().min_by(|p, q| {
                    d(p.matrix(), e_true.matrix()).total_cmp(&d(q.matrix(), e_true.matrix()))
                }) else {
                    continue;
                };
                let s32 = five_point(&a.map(|p| p.cast::<f32>()), &b.map(|p| p.cast::<f32>()));
                match s32 {
                    Err(_) => none += 1,
                    Ok(v) => {
                        let near = v
                            .iter()
                            .any(|e| d(&e.matrix().cast::<f64>(), best.matrix()) < 1e-3);
                        missed += usize::from(!near);
                    }
                }
            }
        }
        for (ty, (r, t, gross, inl, failed)) in ["f32", "f64"].iter().zip(res.iter_mut()) {
            let ok = r.len().max(1);
            println!(
                "| {noise} | {ty} | {} | {} | {gross} | {:.1} | {failed} |",
                stats(r),
                stats(t),
                *inl as f64 / ok as f64
            );
        }
        minimal.push((noise, solved64, none, missed));
    }
    println!("\nMinimal solves on {SUBSETS} random 5-subsets of the true inliers per draw\n");
    println!(
        "| noise px | subsets f64 solves | f32 returns nothing | f32 misses the f64 solution nearest the truth |"
    );
    println!("|---:|---:|---:|---:|");
    for (noise, s, none, missed) in minimal {
        println!(
            "| {noise} | {s} | {none} ({:.2} %) | {missed} ({:.2} %) |",
            100.0 * none as f64 / s.max(1) as f64,
            100.0 * missed as f64 / s.max(1) as f64
        );
    }
}
