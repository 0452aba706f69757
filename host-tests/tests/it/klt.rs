//! KLT against OpenCV and exact motion, on real images (fixtures from
//! `host-tests/scripts/make_klt_fixtures.py`).
//!
//! * pyramids: bit-exact with `cv2.pyrDown`;
//! * known warps of the Middlebury frames (sub-pixel and large shifts, a 3° rotation, a 4 %
//!   scale, a homography): endpoint error against the exact motion, fixed-point and `f32`
//!   paths side by side with OpenCV's `calcOpticalFlowPyrLK` on the same points and images;
//! * the recorded Middlebury pairs: point by point against OpenCV;
//! * Shi-Tomasi corners against `goodFeaturesToTrack`;
//! * the tree and box sequences tracked end to end (survival and round-trip drift).

#![allow(clippy::needless_range_loop)] // 3x3 matrix code reads best with indices.

use std::path::PathBuf;

use camgeom::corners::CornerConfig;
use camgeom::klt::{FlowStatus, LkConfig, TrackerConfig};
use camgeom_host::data_dir;
use camgeom_host::images::{GrayImage, load_gray};
use camgeom_host::klt::{
    Derivatives, Path, corners, flow, flow_pyramids, levels, pyramid, track_sequence,
};
use camgeom_host::known_motion::{Mat3, apply, warp, warps};
use camgeom_host::points::read_csv;

fn fixture(name: &str) -> PathBuf {
    data_dir().join("fixtures").join("klt").join(name)
}

/// The first and second frame of a pair, grey.
fn pair(name: &str) -> (GrayImage, GrayImage) {
    match name {
        "rubberwhale" => (
            load_gray(fixture("rubberwhale1_gray.png")).unwrap(),
            load_gray(fixture("rubberwhale2_gray.png")).unwrap(),
        ),
        _ => (
            load_gray(data_dir().join("middlebury/basketball1.png")).unwrap(),
            load_gray(data_dir().join("middlebury/basketball2.png")).unwrap(),
        ),
    }
}

/// OpenCV's rows `x0,y0,x1,y1,status,err`.
fn opencv_lk(file: &str) -> Vec<[f64; 6]> {
    let t = read_csv(fixture(file), &["x0", "y0", "x1", "y1", "status", "err"]).unwrap();
    t.rows
        .iter()
        .map(|r| [r[0], r[1], r[2], r[3], r[4], r[5]])
        .collect()
}

fn cfg() -> LkConfig {
    // OpenCV's calcOpticalFlowPyrLK defaults but 21x21: winSize 21, maxLevel 3, 30 / 0.01,
    // minEigThreshold 1e-4.
    LkConfig::default()
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        return f64::NAN;
    }
    let k = (p / 100.0 * (v.len() - 1) as f64).round() as usize;
    v[k]
}

#[test]
fn pyramid_is_bit_exact_with_cv_pyrdown() {
    for name in ["rubberwhale", "basketball"] {
        let (a, _) = pair(name);
        let mut buf = Vec::new();
        let p = pyramid(&a, &mut buf, 3);
        for l in 1..3 {
            let want = load_gray(fixture(&format!("{name}_pyr{l}.png"))).unwrap();
            let got = p.level(l).unwrap();
            assert_eq!((got.width(), got.height()), (want.width, want.height));
            let got: Vec<u8> = got.rows().flatten().copied().collect();
            assert!(
                got == want.data,
                "{name} level {l} differs from cv2.pyrDown"
            );
        }
    }
}

#[test]
fn warps_match_the_fixture_images() {
    for name in ["rubberwhale", "basketball"] {
        let (a, _) = pair(name);
        for (wname, h) in warps(a.width, a.height) {
            let b = warp(&a, &h);
            let sum: u64 = b.data.iter().map(|&v| u64::from(v)).sum();
            let want: u64 = std::fs::read_to_string(fixture(&format!("{name}_{wname}_sum.txt")))
                .unwrap()
                .trim()
                .parse()
                .unwrap();
            assert_eq!(
                sum, want,
                "{name} {wname}: the Rust warp differs from the script's"
            );
        }
    }
}

/// Endpoint errors (px) of the tracked points against the exact motion.
fn epe(rows: &[[f64; 6]], h: &Mat3, res: impl Fn(usize) -> Option<(f64, f64)>) -> Vec<f64> {
    rows.iter()
        .enumerate()
        .filter_map(|(k, r)| {
            let (x, y) = res(k)?;
            let (gx, gy) = apply(h, r[0], r[1]);
            Some((x - gx).hypot(y - gy))
        })
        .collect()
}

/// The accuracy table of BENCHMARKS.md: median and 95th-percentile endpoint error, fixed vs
/// f32 vs OpenCV, on the same points and images. Goal: the fixed-point median within 0.05 px of
/// OpenCV's and its 95th percentile no worse (within 0.005 px of rounding).
#[test]
fn known_warps_accuracy_against_opencv() {
    println!(
        "| image | motion | OpenCV tracked | OpenCV median | OpenCV p95 | fixed tracked | fixed median | fixed p95 | f32 tracked | f32 median | f32 p95 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut all = [Vec::new(), Vec::new(), Vec::new()];
    for name in ["rubberwhale", "basketball"] {
        let (a, _) = pair(name);
        for (wname, h) in warps(a.width, a.height) {
            let b = warp(&a, &h);
            let ocv = opencv_lk(&format!("{name}_{wname}_lk.csv"));
            let pts: Vec<[f64; 2]> = ocv.iter().map(|r| [r[0], r[1]]).collect();
            let fx = flow(&a, &b, &pts, &cfg(), Path::Fixed).unwrap();
            let fl = flow(&a, &b, &pts, &cfg(), Path::F32).unwrap();
            let ok = |f: &camgeom_host::klt::FlowPoint| {
                (f.status == FlowStatus::Tracked).then_some((f.x, f.y))
            };
            let mut e_o = epe(&ocv, &h, |k| {
                (ocv[k][4] > 0.5).then_some((ocv[k][2], ocv[k][3]))
            });
            let mut e_x = epe(&ocv, &h, |k| ok(&fx[k]));
            let mut e_f = epe(&ocv, &h, |k| ok(&fl[k]));
            let n = [e_o.len(), e_x.len(), e_f.len()];
            all[0].extend_from_slice(&e_o);
            all[1].extend_from_slice(&e_x);
            all[2].extend_from_slice(&e_f);
            let s = |v: &mut Vec<f64>| (percentile(v, 50.0), percentile(v, 95.0));
            let (om, o95) = s(&mut e_o);
            let (xm, x95) = s(&mut e_x);
            let (fm, f95) = s(&mut e_f);
            println!(
                "| {name} | {wname} | {}/{} | {om:.4} | {o95:.4} | {} | {xm:.4} | {x95:.4} | {} | {fm:.4} | {f95:.4} |",
                n[0],
                pts.len(),
                n[1],
                n[2]
            );
            assert!(
                xm <= om + 0.05,
                "{name} {wname}: fixed median {xm} vs OpenCV {om}"
            );
            assert!(
                fm <= om + 0.05,
                "{name} {wname}: f32 median {fm} vs OpenCV {om}"
            );
            assert!(
                x95 <= o95 + 0.005,
                "{name} {wname}: fixed p95 {x95} vs OpenCV {o95}"
            );
            // Same points tracked, within a few.
            assert!(
                n[1] + 5 >= n[0] && n[2] + 5 >= n[0],
                "{name} {wname}: {n:?}"
            );
        }
    }
    let s = |v: &mut Vec<f64>| (percentile(v, 50.0), percentile(v, 95.0));
    let [o, x, f] = &mut all;
    let ((om, o95), (xm, x95), (fm, f95)) = (s(o), s(x), s(f));
    println!(
        "| all | all | {} | {om:.4} | {o95:.4} | {} | {xm:.4} | {x95:.4} | {} | {fm:.4} | {f95:.4} |",
        o.len(),
        x.len(),
        f.len()
    );
    assert!(xm <= om + 0.05 && x95 <= o95 + 0.005);
}

/// The recorded pairs, point by point against OpenCV (same points, window, levels, criteria).
/// The Rust crate `optical-flow-lk` (a std tracker, not for microcontrollers) on the same
/// known warps and points: 21x21, 4 levels, 30 iterations, its own default texture threshold
/// (1e-3 grey levels² per pixel; OpenCV's minEigThreshold 1e-4 is normalised differently).
/// Only its own numbers are checked (it tracks most points to sub-pixel accuracy); the
/// comparison is printed for BENCHMARKS.md, whoever wins.
#[test]
fn optical_flow_lk_on_the_known_warps() {
    use optical_flow_lk::{TrackParams, TrackStatus, build_pyramid, calc_optical_flow_ex};
    let to_image = |g: &GrayImage| {
        image::GrayImage::from_raw(g.width as u32, g.height as u32, g.data.clone()).unwrap()
    };
    println!(
        "| image | motion | optical-flow-lk tracked | median | p95 | camgeom fixed tracked | median | p95 |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let (mut all, mut ours): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for name in ["rubberwhale", "basketball"] {
        let (a, _) = pair(name);
        let pa = build_pyramid(&to_image(&a), 4);
        for (wname, h) in warps(a.width, a.height) {
            let b = warp(&a, &h);
            let pb = build_pyramid(&to_image(&b), 4);
            let ocv = opencv_lk(&format!("{name}_{wname}_lk.csv"));
            let pts: Vec<(f32, f32)> = ocv.iter().map(|r| (r[0] as f32, r[1] as f32)).collect();
            let params = TrackParams {
                window_size: 21,
                max_iterations: 30,
                min_eigen_threshold: optical_flow_lk::DEFAULT_MIN_EIGEN_THRESHOLD,
            };
            let res = calc_optical_flow_ex(&pa, &pb, &pts, None, params);
            let mut e = epe(&ocv, &h, |k| {
                let r = res.get(k)?;
                (r.status == TrackStatus::Tracked)
                    .then_some((f64::from(r.pos.0), f64::from(r.pos.1)))
            });
            let cpts: Vec<[f64; 2]> = ocv.iter().map(|r| [r[0], r[1]]).collect();
            let fx = flow(&a, &b, &cpts, &cfg(), Path::Fixed).unwrap();
            let mut c = epe(&ocv, &h, |k| {
                let f = fx.get(k)?;
                (f.status == FlowStatus::Tracked).then_some((f.x, f.y))
            });
            let (n, nc) = (e.len(), c.len());
            all.extend_from_slice(&e);
            ours.extend_from_slice(&c);
            let (m, p95) = (percentile(&mut e, 50.0), percentile(&mut e, 95.0));
            let (cm, c95) = (percentile(&mut c, 50.0), percentile(&mut c, 95.0));
            println!(
                "| {name} | {wname} | {n}/{} | {m:.4} | {p95:.4} | {nc} | {cm:.4} | {c95:.4} |",
                pts.len()
            );
            // Both are working trackers: at least half the points on every warp.
            assert!(
                n * 2 >= pts.len(),
                "{name} {wname}: optical-flow-lk tracked {n}"
            );
        }
    }
    let (m, p95) = (percentile(&mut all, 50.0), percentile(&mut all, 95.0));
    let (cm, c95) = (percentile(&mut ours, 50.0), percentile(&mut ours, 95.0));
    println!(
        "| all | all | {} | {m:.4} | {p95:.4} | {} | {cm:.4} | {c95:.4} |",
        all.len(),
        ours.len()
    );
    // optical-flow-lk reports points that did not converge within the iteration cap as
    // `Diverged` (OpenCV and camgeom return their last estimate as tracked), so it keeps
    // fewer, easier points: its median over its own set is not comparable to ours. What is
    // asserted: camgeom tracks more of the points and its 95th percentile over all of them is
    // no worse.
    assert!(
        ours.len() >= all.len() && c95 <= p95,
        "camgeom {} tracked, p95 {c95}; optical-flow-lk {} tracked, p95 {p95}",
        ours.len(),
        all.len()
    );
}

#[test]
fn real_pairs_match_opencv_point_by_point() {
    for name in ["rubberwhale", "basketball"] {
        let (a, b) = pair(name);
        let ocv = opencv_lk(&format!("{name}_real_lk.csv"));
        let pts: Vec<[f64; 2]> = ocv.iter().map(|r| [r[0], r[1]]).collect();
        for path in [Path::Fixed, Path::F32] {
            let ours = flow(&a, &b, &pts, &cfg(), path).unwrap();
            let mut same_status = 0;
            let mut d = Vec::new();
            let mut derr = Vec::new();
            for (o, r) in ours.iter().zip(&ocv) {
                let ok = o.status == FlowStatus::Tracked;
                if ok == (r[4] > 0.5) {
                    same_status += 1;
                }
                if ok && r[4] > 0.5 {
                    d.push((o.x - r[2]).hypot(o.y - r[3]));
                    derr.push((o.err - r[5]).abs());
                }
            }
            let n = ours.len();
            let within = d.iter().filter(|&&v| v < 0.01).count();
            let (m, p95) = (percentile(&mut d, 50.0), percentile(&mut d, 95.0));
            let em = percentile(&mut derr, 50.0);
            println!(
                "{name} {path:?}: status agrees {same_status}/{n}; both tracked {}: |ours - OpenCV| median {m:.2e} p95 {p95:.2e} px, {within} within 0.01 px; |err - OpenCV err| median {em:.2e}",
                d.len()
            );
            assert!(
                same_status * 100 >= n * 98,
                "{name} {path:?}: status {same_status}/{n}"
            );
            assert!(m < 0.002, "{name} {path:?}: median difference {m}");
            assert!(
                within * 100 >= d.len() * 90,
                "{name} {path:?}: {within}/{}",
                d.len()
            );
            assert!(em < 0.01, "{name} {path:?}: error measure differs: {em}");
        }
    }
}

/// Same numbers whether derivatives come per window, per level or by cost, on a real pair.
#[test]
fn per_window_and_per_level_gradients_agree() {
    let (a, b) = pair("basketball");
    let ocv = opencv_lk("basketball_real_lk.csv");
    let pts: Vec<[f64; 2]> = ocv.iter().map(|r| [r[0], r[1]]).collect();
    let c = cfg();
    let l = levels(&c);
    let (mut ba, mut bb) = (Vec::new(), Vec::new());
    let pa = pyramid(&a, &mut ba, l);
    let pb = pyramid(&b, &mut bb, l);
    for path in [Path::Fixed, Path::F32] {
        let w = flow_pyramids(&pa, &pb, &pts, &c, path, Derivatives::Window).unwrap();
        let g = flow_pyramids(&pa, &pb, &pts, &c, path, Derivatives::Level).unwrap();
        assert_eq!(w, g, "{path:?}");
        let a = flow_pyramids(&pa, &pb, &pts, &c, path, Derivatives::Auto).unwrap();
        assert_eq!(w, a, "{path:?}");
    }
}

/// Shi-Tomasi corners against goodFeaturesToTrack (quality 0.01, min distance 10, 400).
#[test]
fn corners_match_good_features_to_track() {
    for name in ["rubberwhale", "basketball"] {
        let (a, _) = pair(name);
        let t = read_csv(fixture(&format!("{name}_corners.csv")), &["x", "y"]).unwrap();
        let ocv: Vec<(f64, f64)> = t.rows.iter().map(|r| (r[0], r[1])).collect();
        let cfg = CornerConfig {
            quality: 0.01,
            min_distance: 10,
            max_corners: 0,
        };
        let ours = corners(&a, &cfg, ocv.len()).unwrap();
        let exact = ocv
            .iter()
            .filter(|o| {
                ours.iter()
                    .any(|c| f64::from(c[0]) == o.0 && f64::from(c[1]) == o.1)
            })
            .count();
        let near = ocv
            .iter()
            .filter(|o| {
                ours.iter().any(|c| {
                    (f64::from(c[0]) - o.0).abs() <= 1.0 && (f64::from(c[1]) - o.1).abs() <= 1.0
                })
            })
            .count();
        // The strongest 50: same pixels.
        let top = ocv
            .iter()
            .take(50)
            .filter(|o| {
                ours.iter()
                    .any(|c| f64::from(c[0]) == o.0 && f64::from(c[1]) == o.1)
            })
            .count();
        println!(
            "{name}: ours {} OpenCV {}; same pixel {exact}, within 1 px {near}, top-50 same pixel {top}",
            ours.len(),
            ocv.len()
        );
        assert_eq!(ours.len(), ocv.len());
        assert!(near * 100 >= ocv.len() * 90, "{name}: {near}/{}", ocv.len());
        assert!(top >= 48, "{name}: top-50 {top}");
    }
}

fn sequence(name: &str) -> Vec<GrayImage> {
    let dir = data_dir().join("sequences").join(name);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    files.iter().map(|p| load_gray(p).unwrap()).collect()
}

/// Tracks `frames` forward then backward to the first frame with no replenishment; returns
/// (tracks at start, survivors, round-trip errors in px).
fn round_trip(frames: &[GrayImage], path: Path) -> (usize, usize, Vec<f64>) {
    let mut seq: Vec<GrayImage> = frames.to_vec();
    seq.extend(frames.iter().rev().skip(1).cloned());
    // replenish_below = 1: detection only while the tracker is empty, i.e. on frame 0.
    let cfg = TrackerConfig {
        lk: LkConfig {
            fb_threshold: Some(1.0),
            ..LkConfig::default()
        },
        corners: CornerConfig {
            quality: 0.01,
            min_distance: 8,
            max_corners: 300,
        },
        replenish_below: 1,
        max_tracks: 0,
    };
    let all = track_sequence(&seq, &cfg, path, |_, _| {}).unwrap();
    let last = seq.len() - 1;
    let start: Vec<_> = all.iter().filter(|r| r.frame == 0).collect();
    let end: Vec<_> = all
        .iter()
        .filter(|r| r.frame == last && r.age as usize == last)
        .collect();
    let errs = end
        .iter()
        .map(|e| {
            let s = start.iter().find(|s| s.id == e.id).unwrap();
            (e.x - s.x).hypot(e.y - s.y)
        })
        .collect();
    (start.len(), end.len(), errs)
}

/// Tree (68 frames, handheld, a hand passes late) and box (150 frames, a box moved by hand):
/// features detected on frame 0, tracked to frame K and back to frame 0 (forward-backward
/// check 1 px per step). Stated: at least 40 % of the features survive the round trip over the
/// first 30 frames of each sequence, and the survivors return to within 0.5 px (median) and
/// 2 px (95 %) of where they started, on both arithmetic paths.
#[test]
fn sequences_round_trip_survival_and_drift() {
    for name in ["tree", "box"] {
        let frames = sequence(name);
        assert!(frames.len() >= 60);
        for path in [Path::Fixed, Path::F32] {
            let (n0, n1, mut e) = round_trip(&frames[..30], path);
            let (m, p95) = (percentile(&mut e, 50.0), percentile(&mut e, 95.0));
            println!(
                "{name} {path:?}: {n1}/{n0} survive 30 frames and back; drift median {m:.3} px, p95 {p95:.3} px"
            );
            assert!(n1 * 100 >= n0 * 40, "{name} {path:?}: {n1}/{n0}");
            assert!(m < 0.5 && p95 < 2.0, "{name} {path:?}: {m} {p95}");
        }
    }
}

/// The whole sequences with replenishment: the tracker keeps a healthy population and every id
/// is unique and monotone.
#[test]
fn sequences_tracked_end_to_end_with_replenishment() {
    for name in ["tree", "box"] {
        let frames = sequence(name);
        let cfg = TrackerConfig {
            lk: LkConfig {
                fb_threshold: Some(1.0),
                ..LkConfig::default()
            },
            corners: CornerConfig {
                quality: 0.01,
                min_distance: 8,
                max_corners: 0,
            },
            replenish_below: 150,
            max_tracks: 0,
        };
        let mut min_count = usize::MAX;
        let rows = track_sequence(&frames, &cfg, Path::Fixed, |_, r| {
            min_count = min_count.min(r.len())
        })
        .unwrap();
        let ids: std::collections::BTreeSet<u32> = rows.iter().map(|r| r.id).collect();
        let max_age = rows.iter().map(|r| r.age).max().unwrap();
        println!(
            "{name}: {} frames, {} tracks in all, fewest live {min_count}, longest track {max_age} frames",
            frames.len(),
            ids.len()
        );
        assert!(min_count >= 100, "{name}: {min_count}");
        assert!(max_age as usize >= frames.len() / 3, "{name}: {max_age}");
        for k in 0..frames.len() {
            let mut f: Vec<u32> = rows.iter().filter(|r| r.frame == k).map(|r| r.id).collect();
            let n = f.len();
            f.dedup();
            assert_eq!(f.len(), n);
        }
    }
}
