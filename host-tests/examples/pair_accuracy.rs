//! Relative-pose accuracy of the features and matching that structure from motion uses
//! ([`camgeom_host::cli::matches::orb_features`] and
//! [`camgeom_host::cli::matches::match_features`]) on the real buildings of
//! `data/multiview/`, scored against the sets' true cameras.
//!
//! For every pair of views `(i, i + 1)` and `(i, i + 2)`: the features of both images, their
//! matches, then [`camgeom::twoview::find_essential`] (5-point RANSAC in f64, 1 px Sampson
//! threshold, p = 0.999) and [`camgeom::twoview::recover_pose`]. Printed per pair: features
//! of both views, matches, inliers, the rotation error (the angle of `R_est R_ijᵀ`, degrees),
//! the translation-direction error (degrees) and the time (features of both views, matching,
//! geometry); then the median and maximum per set. The truth: `R_ij = R_j R_iᵀ`,
//! `t_ij = t_j - R_ij t_i` from `cameras.json` (`X_cam = R X_world + t`). A set with only a
//! `camera.json` (K, no poses, such as `sceaux-castle`) is scored by its inlier ratio.
//!
//! `scripts/pair_accuracy_opencv.py` prints the same table for OpenCV's SIFT, the baseline.
//!
//! ```sh
//! cargo run --release -p camgeom-host --example pair_accuracy [SET ...]
//! ```
//!
//! `SET` is a folder name under `data/multiview/` (default: `herz-jesus-p8 entry-p10`).
//! `PAIR_SEEDS=K` runs RANSAC with `K` seeds per pair and prints each pair's median errors
//! and inliers over them (default 1: RANSAC's default seed), which steadies comparisons.

use std::path::{Path, PathBuf};
use std::time::Instant;

use camgeom::features::orb::Feature;
use camgeom::nalgebra::{Matrix3, Point2, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::twoview::{find_essential, recover_pose};
use camgeom_host::cli::matches::{match_features, orb_features};
use serde_json::Value;

/// One view: its image, K, and its pose when the set has one.
struct View {
    file: PathBuf,
    k: Matrix3<f64>,
    pose: Option<(Matrix3<f64>, Vector3<f64>)>,
}

fn matrix(v: &Value) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| v[r][c].as_f64().unwrap_or(f64::NAN))
}

fn views(dir: &Path) -> Vec<View> {
    let cameras = dir.join("cameras.json");
    if let Ok(text) = std::fs::read_to_string(&cameras) {
        let v: Value = serde_json::from_str(&text).expect("cameras.json");
        return v["cameras"]
            .as_array()
            .expect("cameras")
            .iter()
            .map(|c| View {
                file: dir.join(c["file"].as_str().expect("file")),
                k: matrix(&c["K"]),
                pose: Some((
                    matrix(&c["R_world_to_camera"]),
                    Vector3::from_fn(|i, _| c["t_world_to_camera"][i].as_f64().unwrap_or(0.0)),
                )),
            })
            .collect();
    }
    let spec = camgeom_host::load_camera(dir.join("camera.json")).expect("camera.json");
    let k = spec.camera.intrinsics.matrix();
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("set folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "jpg" || x == "png"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|file| View {
            file,
            k,
            pose: None,
        })
        .collect()
}

fn angle_deg(r: &Matrix3<f64>) -> f64 {
    ((r.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `(matches, inliers, (rotation error, translation error) when the set has poses)`.
type PairResult = (usize, usize, Option<(f64, f64)>);

/// The matches, inliers and errors of one pair (medians over the seeds), or why it failed.
fn pair(
    a: (&View, &[Feature]),
    b: (&View, &[Feature]),
    what: &str,
    seeds: u64,
) -> Result<PairResult, String> {
    let matches = match_features(a.1, b.1, what).map_err(|e| e.to_string())?;
    let mut runs = Vec::new();
    for s in 0..seeds {
        runs.push(geometry(a, b, &matches, s)?);
    }
    let mut inl: Vec<f64> = runs.iter().map(|r| r.0 as f64).collect();
    let errors = runs.iter().all(|r| r.1.is_some()).then(|| {
        let mut rot: Vec<f64> = runs.iter().filter_map(|r| r.1.map(|e| e.0)).collect();
        let mut tr: Vec<f64> = runs.iter().filter_map(|r| r.1.map(|e| e.1)).collect();
        (median(&mut rot), median(&mut tr))
    });
    Ok((matches.len(), median(&mut inl) as usize, errors))
}

/// `(inliers, errors)` of the essential matrix and pose of `matches` with RANSAC seed
/// number `seed` (0: the default seed).
fn geometry(
    a: (&View, &[Feature]),
    b: (&View, &[Feature]),
    matches: &[(usize, usize)],
    seed: u64,
) -> Result<(usize, Option<(f64, f64)>), String> {
    let pt = |f: &Feature| Point2::new(f64::from(f.keypoint.x), f64::from(f.keypoint.y));
    let x1: Vec<_> = matches.iter().map(|&(i, _)| pt(&a.1[i])).collect();
    let x2: Vec<_> = matches.iter().map(|&(_, j)| pt(&b.1[j])).collect();
    let k1 = camgeom::camera::Intrinsics::from_matrix(&a.0.k).map_err(|e| e.to_string())?;
    let k2 = camgeom::camera::Intrinsics::from_matrix(&b.0.k).map_err(|e| e.to_string())?;
    let params = RansacConfig {
        threshold: 1.0,
        confidence: 0.999,
        max_iterations: 2000,
        seed: RansacConfig::<f64>::default().seed.wrapping_add(seed),
        ..RansacConfig::default()
    }
    .check()
    .map_err(|e| e.to_string())?;
    let mut mask = vec![false; x1.len()];
    let (e, _) =
        find_essential(&k1, &k2, &x1, &x2, &params, &mut mask).map_err(|e| e.to_string())?;
    let rp = recover_pose(&e, &k1, &k2, &x1, &x2, 50.0, &mut mask).map_err(|e| e.to_string())?;
    let inliers = mask.iter().filter(|&&m| m).count();
    let errors = a.0.pose.zip(b.0.pose).map(|((ri, ti), (rj, tj))| {
        let rij = rj * ri.transpose();
        let tij = tj - rij * ti;
        let r_est = rp.pose.rotation().into_inner();
        let t_est = rp.pose.translation();
        let rot = angle_deg(&(r_est * rij.transpose()));
        let cos = t_est.normalize().dot(&tij.normalize()).clamp(-1.0, 1.0);
        (rot, cos.acos().to_degrees())
    });
    Ok((inliers, errors))
}

fn main() {
    let mut sets: Vec<String> = std::env::args().skip(1).collect();
    if sets.is_empty() {
        sets = vec!["herz-jesus-p8".into(), "entry-p10".into()];
    }
    let seeds: u64 = std::env::var("PAIR_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
        .max(1);
    for set in &sets {
        let dir = camgeom_host::data_dir().join("multiview").join(set);
        let views = views(&dir);
        let mut feats = Vec::new();
        let mut feat_ms = Vec::new();
        for v in &views {
            let t0 = Instant::now();
            feats.push(orb_features(&v.file).expect("features"));
            feat_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        println!("== {set}");
        println!(
            "{:>7} {:>11} {:>7} {:>7} {:>6} {:>8} {:>8} {:>8}",
            "pair", "features", "matches", "inliers", "ratio", "rot_deg", "t_deg", "ms"
        );
        let (mut rots, mut trs, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
        for step in [1, 2] {
            for i in 0..views.len().saturating_sub(step) {
                let j = i + step;
                let what = format!("{set} {i}-{j}");
                let t0 = Instant::now();
                let r = pair((&views[i], &feats[i]), (&views[j], &feats[j]), &what, seeds);
                let ms = t0.elapsed().as_secs_f64() * 1e3 + feat_ms[i] + feat_ms[j];
                let nf = format!("{}/{}", feats[i].len(), feats[j].len());
                match r {
                    Ok((m, n, err)) => {
                        let ratio = n as f64 / m.max(1) as f64;
                        ratios.push(ratio);
                        let (rot, tr) = err.unwrap_or((f64::NAN, f64::NAN));
                        if err.is_some() {
                            rots.push(rot);
                            trs.push(tr);
                        }
                        println!(
                            "{:>7} {nf:>11} {m:>7} {n:>7} {ratio:>6.3} {rot:>8.3} {tr:>8.3} {ms:>8.0}",
                            format!("{i}-{j}")
                        );
                    }
                    Err(e) => {
                        // A failed pair counts as 180° off.
                        if views[i].pose.is_some() {
                            rots.push(180.0);
                            trs.push(180.0);
                        }
                        println!("{:>7} {nf:>11} failed: {e}", format!("{i}-{j}"));
                    }
                }
            }
        }
        let max = |v: &[f64]| v.iter().copied().fold(f64::NAN, f64::max);
        let min = |v: &[f64]| v.iter().copied().fold(f64::NAN, f64::min);
        println!(
            "{set}: {} pairs; rotation median {:.3} max {:.3} deg; translation median {:.3} max {:.3} deg; inlier ratio median {:.3} min {:.3}; features/view median {:.0}; ms/view {:.0}",
            ratios.len(),
            median(&mut rots.clone()),
            max(&rots),
            median(&mut trs.clone()),
            max(&trs),
            median(&mut ratios.clone()),
            min(&ratios),
            median(&mut feats.iter().map(|f| f.len() as f64).collect::<Vec<_>>()),
            median(&mut feat_ms),
        );
    }
}
