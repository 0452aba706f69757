//! camgeom's FAST, ORB and matching on real images, side by side with OpenCV's figures
//! (`host-tests/scripts/make_feature_fixtures.py` writes them into `data/features/`).
//!
//! Run with `--nocapture` to see the measured figures next to OpenCV's.

use std::collections::HashSet;
use std::path::PathBuf;

use camgeom::features::fast::{self, FastConfig};
use camgeom::features::orb::{self, Feature, OrbConfig};
use camgeom::features::{Descriptor, Match, MatchConfig, match_descriptors};
use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::ransac::RansacParams;
use camgeom_host::images::{GrayImage, load_gray};

const CAP: usize = 500;

fn data(folder: &str, name: &str) -> PathBuf {
    camgeom_host::data_dir().join(folder).join(name)
}

fn figures() -> serde_json::Value {
    let text = std::fs::read_to_string(data("features", "opencv_orb_figures.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn h1to3() -> Matrix3<f64> {
    let fs = camgeom_host::FileStorage::open(data("oxford-graf", "H1to3p.xml")).unwrap();
    fs.matrix("H13").unwrap().to_matrix3().unwrap()
}

fn apply(h: &Matrix3<f64>, p: Point2<f64>) -> Point2<f64> {
    Point2::from_homogeneous(h * p.to_homogeneous()).unwrap()
}

fn orb_features(img: &GrayImage, config: &OrbConfig) -> camgeom::heapless::Vec<Feature, CAP> {
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, config.scale_q8)];
    let mut out = camgeom::heapless::Vec::new();
    let params = config.check().unwrap();
    orb::orb_detect(&img.view().unwrap(), &params, &mut scratch, &mut out).unwrap();
    out
}

fn matches(a: &[Feature], b: &[Feature], config: &MatchConfig) -> Vec<Match> {
    let da: Vec<Descriptor> = a.iter().map(|f| f.descriptor).collect();
    let db: Vec<Descriptor> = b.iter().map(|f| f.descriptor).collect();
    let mut out = vec![Match::default(); da.len()];
    let mut scratch = vec![0u32; camgeom::features::matching::scratch_len(db.len())];
    let params = config.check().unwrap();
    let n = match_descriptors(&da, &db, &params, &mut scratch, &mut out).unwrap();
    out.truncate(n);
    out
}

fn point(f: &Feature) -> Point2<f64> {
    Point2::new(f.keypoint.x.into(), f.keypoint.y.into())
}

/// Cross-check only, as OpenCV's `BFMatcher(NORM_HAMMING, crossCheck=True)`.
const CROSS_CHECK: MatchConfig = MatchConfig {
    ratio: 1.0,
    cross_check: true,
    max_distance: 256,
};

/// FAST-9 with the same threshold and non-maximum suppression as
/// `cv2.FastFeatureDetector(threshold=20, nonmaxSuppression=True)` on box_in_scene.png.
///
/// Measure: the Jaccard index `|A ∩ B| / |A ∪ B|` of the two sets of corner pixels, and the
/// score agreement on the common corners. Both implement the same definition (segment test,
/// OpenCV's `cornerScore`, strict 3x3 maximum), so the sets should be identical: the only
/// legitimate difference would be a corner within 3 px of the border (both skip the 3-px
/// ring), hence the bar of 0.999 rather than exactly 1.
#[test]
fn fast_agrees_with_opencv() {
    let img = load_gray(data("features", "box_in_scene.png")).unwrap();
    let text = std::fs::read_to_string(data("features", "fast_box_in_scene.csv")).unwrap();
    let theirs: Vec<(u16, u16, u8)> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<u16> = l.split(',').map(|t| t.parse().unwrap()).collect();
            (v[0], v[1], v[2] as u8)
        })
        .collect();
    let mut scratch = vec![0u8; fast::scratch_len(img.width)];
    let mut ours = Vec::new();
    let config = FastConfig {
        threshold: 20,
        nonmax: true,
        border: 3,
    };
    fast::fast_detect(
        &img.view().unwrap(),
        &config.check().unwrap(),
        &mut scratch,
        |c| ours.push((c.x, c.y, c.score)),
    )
    .unwrap();
    let a: HashSet<(u16, u16)> = ours.iter().map(|c| (c.0, c.1)).collect();
    let b: HashSet<(u16, u16)> = theirs.iter().map(|c| (c.0, c.1)).collect();
    let common = a.intersection(&b).count();
    let jaccard = common as f64 / a.union(&b).count() as f64;
    let same_score = ours.iter().filter(|c| theirs.contains(c)).count();
    println!(
        "FAST box_in_scene t=20: camgeom {} corners, OpenCV {}, common {common}, Jaccard {jaccard:.4}, same score {same_score}",
        a.len(),
        b.len()
    );
    assert!(jaccard >= 0.999, "Jaccard {jaccard}");
    assert_eq!(same_score, common);
}

/// ORB + cross-check matching graf1 -> graf3: the fraction of matches that the ground-truth
/// homography confirms within 3 px, against OpenCV's ORB (500 features) + BFMatcher
/// (crossCheck) on the same images.
#[test]
fn orb_matches_graf1_to_graf3_as_well_as_opencv() {
    let g1 = load_gray(data("oxford-graf", "graf1.png")).unwrap();
    let g3 = load_gray(data("oxford-graf", "graf3.png")).unwrap();
    let config = OrbConfig::default();
    let (f1, f3) = (orb_features(&g1, &config), orb_features(&g3, &config));
    let h = h1to3();
    let correct = |ms: &[Match]| {
        ms.iter()
            .filter(|m| {
                let p = point(&f1[usize::from(m.query)]);
                let q = point(&f3[usize::from(m.train)]);
                (apply(&h, p) - q).norm() < 3.0
            })
            .count()
    };
    let cc = matches(&f1, &f3, &CROSS_CHECK);
    let cc_ok = correct(&cc);
    let ratio = matches(
        &f1,
        &f3,
        &MatchConfig {
            ratio: 0.8,
            cross_check: false,
            max_distance: 256,
        },
    );
    let ratio_ok = correct(&ratio);
    let fig = &figures()["graf1_to_graf3"];
    let cv_frac = fig["crosscheck_fraction_3px"].as_f64().unwrap();
    let cv_correct = fig["crosscheck_correct_3px"].as_u64().unwrap();
    let frac = cc_ok as f64 / cc.len() as f64;
    println!(
        "graf1->graf3 ORB {}+{} features; cross-check: camgeom {cc_ok}/{} = {frac:.3} correct (3 px), \
         OpenCV {cv_correct}/{} = {cv_frac:.3}; ratio 0.8: camgeom {ratio_ok}/{} = {:.3}, OpenCV {:.3} of {}",
        f1.len(),
        f3.len(),
        cc.len(),
        fig["crosscheck_matches"],
        ratio.len(),
        ratio_ok as f64 / ratio.len() as f64,
        fig["ratio08_fraction_3px"].as_f64().unwrap(),
        fig["ratio08_matches"],
    );
    assert_eq!((f1.len(), f3.len()), (CAP, CAP));
    // Within 15 % of OpenCV's share and count of correct matches. Measured: camgeom
    // 87/163 = 0.53, OpenCV 98/172 = 0.57 with cross-check; with the 0.8 ratio test camgeom
    // has more correct matches (73 of 105 against 57 of 77). The gap is OpenCV's learned test
    // pattern against this crate's Gaussian one (other σ and radii scored 85..92 correct here,
    // within noise of each other); on box_in_scene camgeom is ahead (`box_found_in_scene`).
    assert!(frac >= 0.85 * cv_frac, "{frac} vs OpenCV {cv_frac}");
    assert!(
        cc_ok as f64 >= 0.85 * cv_correct as f64,
        "{cc_ok} vs OpenCV {cv_correct}"
    );
    // The ratio test keeps at least as many correct matches as OpenCV's.
    let cv_ratio_ok =
        fig["ratio08_fraction_3px"].as_f64().unwrap() * fig["ratio08_matches"].as_f64().unwrap();
    assert!(
        ratio_ok as f64 >= 0.9 * cv_ratio_ok,
        "{ratio_ok} vs OpenCV {cv_ratio_ok}"
    );
}

/// ORB + cross-check + camgeom's RANSAC (with local optimisation and LM refinement) on
/// graf1 -> graf3: mean transfer error over a 40-px grid of graf1 points whose true image lies
/// inside graf3, against H1to3p, side by side with OpenCV's ORB + BFMatcher + findHomography.
#[test]
fn graf_homography_from_features_and_ransac() {
    let g1 = load_gray(data("oxford-graf", "graf1.png")).unwrap();
    let g3 = load_gray(data("oxford-graf", "graf3.png")).unwrap();
    let config = OrbConfig::default();
    let (f1, f3) = (orb_features(&g1, &config), orb_features(&g3, &config));
    let ms = matches(&f1, &f3, &CROSS_CHECK);
    let src: Vec<Point2<f64>> = ms
        .iter()
        .map(|m| point(&f1[usize::from(m.query)]))
        .collect();
    let dst: Vec<Point2<f64>> = ms
        .iter()
        .map(|m| point(&f3[usize::from(m.train)]))
        .collect();
    let mut mask = vec![false; ms.len()];
    let (h_est, report) = find_homography(&src, &dst, &RansacParams::default(), &mut mask).unwrap();
    let h_true = h1to3();
    let truth = Homography::from_matrix(&h_true).unwrap();
    let (w, hgt) = (g1.width as f64, g1.height as f64);
    let mut errors = Vec::new();
    for y in (0..g1.height).step_by(40) {
        for x in (0..g1.width).step_by(40) {
            let p = Point2::new(x as f64, y as f64);
            let q = truth.transfer(&p).unwrap();
            if q.x >= 0.0 && q.x <= w - 1.0 && q.y >= 0.0 && q.y <= hgt - 1.0 {
                errors.push((h_est.transfer(&p).unwrap() - q).norm());
            }
        }
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().cloned().fold(0.0, f64::max);
    let fig = &figures()["graf1_to_graf3"];
    let cv_mean = fig["grid_mean_transfer_error_px"].as_f64().unwrap();
    println!(
        "graf1->graf3 RANSAC: camgeom {} inliers of {} matches, grid ({} points) mean {mean:.3} px, max {max:.3} px; \
         OpenCV {} inliers, mean {cv_mean:.3} px, max {:.3} px",
        report.inliers,
        ms.len(),
        errors.len(),
        fig["ransac_inliers"],
        fig["grid_max_transfer_error_px"].as_f64().unwrap()
    );
    assert_eq!(errors.len() as u64, fig["grid_points"].as_u64().unwrap());
    // Measured: camgeom 0.52 px mean (1.4 px max), OpenCV 2.05 px (6.4 px max).
    assert!(mean < 1.0, "mean transfer error {mean}");
    assert!(mean <= cv_mean, "{mean} vs OpenCV {cv_mean}");
}

/// box.png located in box_in_scene.png: camgeom ORB + cross-check + RANSAC, the projected
/// outline compared with the reference outline (OpenCV SIFT + ratio + RANSAC, recorded by the
/// script), and the matches consistent with each other (a large RANSAC consensus).
#[test]
fn box_found_in_scene() {
    let bx = load_gray(data("features", "box.png")).unwrap();
    let scene = load_gray(data("features", "box_in_scene.png")).unwrap();
    let config = OrbConfig::default();
    let (fa, fb) = (orb_features(&bx, &config), orb_features(&scene, &config));
    let ms = matches(&fa, &fb, &CROSS_CHECK);
    let src: Vec<Point2<f64>> = ms
        .iter()
        .map(|m| point(&fa[usize::from(m.query)]))
        .collect();
    let dst: Vec<Point2<f64>> = ms
        .iter()
        .map(|m| point(&fb[usize::from(m.train)]))
        .collect();
    let mut mask = vec![false; ms.len()];
    let (h, report) = find_homography(&src, &dst, &RansacParams::default(), &mut mask).unwrap();
    let (w, hh) = ((bx.width - 1) as f64, (bx.height - 1) as f64);
    let corners = [(0.0, 0.0), (w, 0.0), (w, hh), (0.0, hh)];
    let fig = &figures()["box_in_scene"];
    let reference = fig["reference_outline_sift"].as_array().unwrap();
    let mut worst = 0.0f64;
    for ((x, y), r) in corners.iter().zip(reference) {
        let q = h.transfer(&Point2::new(*x, *y)).unwrap();
        let r = Point2::new(r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
        worst = worst.max((q - r).norm());
    }
    println!(
        "box in scene: camgeom {} features, {} matches, {} RANSAC inliers, outline max corner error {worst:.2} px \
         vs the SIFT reference; OpenCV ORB: {} matches, {} inliers, {:.2} px",
        fb.len(),
        ms.len(),
        report.inliers,
        fig["orb_crosscheck_matches"],
        fig["orb_ransac_inliers"],
        fig["orb_outline_max_corner_error_px"].as_f64().unwrap()
    );
    // Matches consistent with each other: a consensus far above chance (measured 37 of 110;
    // OpenCV's ORB pipeline gets 29).
    assert!(report.inliers >= 25, "{}", report.inliers);
    // The box's outline within 10 px of the reference at every corner (the box is ~170 px
    // wide; measured 7.7 px, OpenCV's ORB pipeline 10.7 px).
    assert!(worst < 10.0, "{worst}");
}

/// ORB features of `img` into a buffer sized at run time ([`orb::grid_capacity`]).
fn orb_features_into(img: &GrayImage, config: &OrbConfig) -> Vec<Feature> {
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, config.scale_q8)];
    let mut out = vec![Feature::default(); orb::grid_capacity(img.width, img.height, config)];
    let params = config.check().unwrap();
    let n = orb::orb_detect_into(&img.view().unwrap(), &params, &mut scratch, &mut out).unwrap();
    out.truncate(n);
    out
}

/// The OpenCV-rendered polygon scene (`scripts/make_subpixel_fixtures.py`) moved by
/// `(dx, dy)` hundredths of a pixel.
fn subpixel_scene(dx: u32, dy: u32) -> GrayImage {
    load_gray(data(
        "features",
        &format!("subpixel_scene_{dx:03}_{dy:03}.png"),
    ))
    .unwrap()
}

/// `(rms, count)` of the displacement errors of the features of `a` found again in `b`
/// (the nearest feature of the same level within 1.5 px of `p + shift`), against `shift`.
fn shift_errors(a: &[Feature], b: &[Feature], shift: (f64, f64)) -> (f64, usize) {
    let (mut sq, mut n) = (0.0, 0);
    for f in a {
        let want = Point2::new(point(f).x + shift.0, point(f).y + shift.1);
        let near = b
            .iter()
            .filter(|g| g.keypoint.level == f.keypoint.level)
            .map(|g| (point(g) - want).norm())
            .fold(f64::INFINITY, f64::min);
        if near < 1.5 {
            sq += near * near;
            n += 1;
        }
    }
    ((sq / n.max(1) as f64).sqrt(), n)
}

/// Sub-pixel keypoints follow sub-pixel motion: the scene rendered by OpenCV (16x supersampled
/// polygons, area-averaged) moved by (0.25, 0.5), (0.5, 0.25) and (0.75, 0.75) px; each
/// feature of the unmoved scene is found again in the moved one and its displacement compared
/// with the true shift.
///
/// Measure: the RMS displacement error over the features found again, single level. Integer
/// keypoints measured 0.66 to 0.75 px (the fractional shift rounded, and FAST's pixel moving
/// along the edges); the edge fit ([`orb::subpixel_offset`]) 0.30 to 0.36 px (its tail: windows
/// crossed by the edges of other polygons). Bars: below 0.45 px, and under 0.6 times the
/// integer error, on every shift.
#[test]
fn orb_subpixel_keypoints_follow_known_shifts() {
    let base = subpixel_scene(0, 0);
    let cfg = |subpixel| OrbConfig {
        levels: 1,
        max_features: 400,
        subpixel,
        ..OrbConfig::default()
    };
    let (ia, sa) = (
        orb_features_into(&base, &cfg(false)),
        orb_features_into(&base, &cfg(true)),
    );
    for (dx, dy) in [(25, 50), (50, 25), (75, 75)] {
        let moved = subpixel_scene(dx, dy);
        let shift = (f64::from(dx) / 100.0, f64::from(dy) / 100.0);
        let (int_rms, int_n) = shift_errors(&ia, &orb_features_into(&moved, &cfg(false)), shift);
        let (sub_rms, sub_n) = shift_errors(&sa, &orb_features_into(&moved, &cfg(true)), shift);
        println!(
            "shift ({dx}, {dy})/100 px: integer rms {int_rms:.3} px ({int_n} found), \
             sub-pixel {sub_rms:.3} px ({sub_n} found)"
        );
        assert!(sub_n >= 60 && int_n >= 60, "{sub_n} {int_n}");
        assert!(sub_rms < 0.45, "{sub_rms}");
        assert!(sub_rms < 0.6 * int_rms, "{sub_rms} vs {int_rms}");
    }
}

/// Sub-pixel keypoints land on the polygons' true vertices (`subpixel_vertices.csv`, where
/// OpenCV drew them): per feature with a vertex within 2 px, the distance to the nearest one.
///
/// Measure: the median distance. Integer keypoints measured 1.33 px (48 features within 2 px:
/// FAST's pixel sits inside the corner), sub-pixel 0.21 px (71 within 2 px). Bars: sub-pixel
/// below 0.4 px and under 0.6 times the integer median.
#[test]
fn orb_subpixel_keypoints_land_on_true_vertices() {
    let text = std::fs::read_to_string(data("features", "subpixel_vertices.csv")).unwrap();
    let vertices: Vec<Point2<f64>> = text
        .lines()
        .skip(1)
        .map(|l| {
            let (x, y) = l.split_once(',').unwrap();
            Point2::new(x.parse().unwrap(), y.parse().unwrap())
        })
        .collect();
    let base = subpixel_scene(0, 0);
    let median_distance = |subpixel| {
        let cfg = OrbConfig {
            levels: 1,
            max_features: 400,
            subpixel,
            ..OrbConfig::default()
        };
        let mut d: Vec<f64> = orb_features_into(&base, &cfg)
            .iter()
            .map(|f| {
                vertices
                    .iter()
                    .map(|v| (point(f) - v).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .filter(|&d| d < 2.0)
            .collect();
        d.sort_by(f64::total_cmp);
        (d[d.len() / 2], d.len())
    };
    let ((int_med, int_n), (sub_med, sub_n)) = (median_distance(false), median_distance(true));
    println!(
        "median distance to the vertex: integer {int_med:.3} px ({int_n}), sub-pixel {sub_med:.3} px ({sub_n})"
    );
    assert!(sub_n >= 40, "{sub_n}");
    assert!(
        sub_med < 0.4 && sub_med < 0.6 * int_med,
        "{sub_med} vs {int_med}"
    );
}

/// The grid ([`OrbConfig::grid_cell`]) bounds the features of a cell and spreads them: on a
/// real photograph (herz-jesus-p8 view 0, 1536x1024, single level), 32-px cells keeping 2.
///
/// Measure: the most features in one cell, and the cells covered, with and without the grid,
/// for the same count (1000). Without a grid the strongest corners crowd on the building's
/// carved stone (up to 31 in a cell, 238 cells covered, measured); with it no cell holds more
/// than 2 and 808 cells are covered. Bars: at most `cell_keep` a cell, and
/// a third more cells covered.
#[test]
fn orb_grid_bounds_features_per_cell() {
    let img = load_gray(data("multiview/herz-jesus-p8", "0000.jpg")).unwrap();
    let (cell, keep) = (32usize, 2u8);
    let base = OrbConfig {
        levels: 1,
        max_features: 1000,
        ..OrbConfig::default()
    };
    let grid = OrbConfig {
        grid_cell: cell as u16,
        cell_keep: keep,
        ..base
    };
    let per_cell = |fs: &[Feature]| {
        let mut counts = std::collections::HashMap::<(usize, usize), usize>::new();
        for f in fs {
            let k = (f.keypoint.x as usize / cell, f.keypoint.y as usize / cell);
            *counts.entry(k).or_default() += 1;
        }
        (counts.values().copied().max().unwrap_or(0), counts.len())
    };
    let (fa, fb) = (
        orb_features_into(&img, &base),
        orb_features_into(&img, &grid),
    );
    let ((most_a, cells_a), (most_b, cells_b)) = (per_cell(&fa), per_cell(&fb));
    println!(
        "without grid: {} features, at most {most_a} a cell, {cells_a} cells; \
         with: {} features, at most {most_b} a cell, {cells_b} cells",
        fa.len(),
        fb.len()
    );
    assert_eq!(fb.len(), 1000);
    assert!(most_b <= usize::from(keep), "{most_b}");
    assert!(cells_b * 3 > cells_a * 4, "{cells_b} vs {cells_a}");
    // Strongest first, as without a grid.
    assert!(
        fb.windows(2)
            .all(|p| p[0].keypoint.response >= p[1].keypoint.response)
    );
}

/// The relative pose of two real photographs from the features and matching structure from
/// motion uses (`camgeom_host::cli::matches::{orb_features, match_features}`), then
/// `find_essential` (1 px, p = 0.999) and `recover_pose`, against the benchmark's cameras:
/// herz-jesus-p8 views 1 and 3, and entry-p10 views 0 and 2 (two views apart each).
///
/// Measure (`examples/pair_accuracy.rs`): rotation errors of 0.10 and 0.07 deg, translation
/// directions 0.05 and 0.29 deg, 333 and 980 inliers (RANSAC's default seed; over 5 seeds the
/// medians are 0.06 and 0.11 deg). OpenCV's SIFT + ratio 0.75 + `findEssentialMat` gives 0.23
/// and 0.44 deg on these pairs, the 500 integer ORB features of before 5.5 and 1.5 deg. Bars:
/// rotation under 0.3 deg, translation direction under 1 deg, at least 250 inliers.
#[test]
fn sfm_features_give_real_relative_poses() {
    use camgeom::camera::Intrinsics;
    use camgeom::ransac::RansacConfig;
    use camgeom::twoview::{find_essential, recover_pose};
    use camgeom_host::cli::matches::{match_features, orb_features};
    let cameras = |set: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(data(set, "cameras.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let m3 = |v: &serde_json::Value| Matrix3::from_fn(|r, c| v[r][c].as_f64().unwrap());
    for (set, i, j) in [
        ("multiview/herz-jesus-p8", 1, 3),
        ("multiview/entry-p10", 0, 2),
    ] {
        let cams = cameras(set);
        let cam = |k: usize| &cams["cameras"][k];
        let feats = |k: usize| orb_features(&data(set, cam(k)["file"].as_str().unwrap())).unwrap();
        let (fa, fb) = (feats(i), feats(j));
        let m = match_features(&fa, &fb, set).unwrap();
        let x1: Vec<Point2<f64>> = m.iter().map(|&(a, _)| point(&fa[a])).collect();
        let x2: Vec<Point2<f64>> = m.iter().map(|&(_, b)| point(&fb[b])).collect();
        let k1 = Intrinsics::from_matrix(&m3(&cam(i)["K"])).unwrap();
        let k2 = Intrinsics::from_matrix(&m3(&cam(j)["K"])).unwrap();
        let params = RansacConfig {
            threshold: 1.0,
            confidence: 0.999,
            ..RansacConfig::default()
        }
        .check()
        .unwrap();
        let mut mask = vec![false; x1.len()];
        let (e, _) = find_essential(&k1, &k2, &x1, &x2, &params, &mut mask).unwrap();
        let rp = recover_pose(&e, &k1, &k2, &x1, &x2, 50.0, &mut mask).unwrap();
        let (ri, rj) = (
            m3(&cam(i)["R_world_to_camera"]),
            m3(&cam(j)["R_world_to_camera"]),
        );
        let t = |k: usize| {
            camgeom::nalgebra::Vector3::from_fn(|r, _| {
                cam(k)["t_world_to_camera"][r].as_f64().unwrap()
            })
        };
        let rij = rj * ri.transpose();
        let tij = t(j) - rij * t(i);
        let d = rp.pose.rotation().into_inner() * rij.transpose();
        let rot = ((d.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        let cos = rp.pose.translation().normalize().dot(&tij.normalize());
        let tr = cos.clamp(-1.0, 1.0).acos().to_degrees();
        let inliers = mask.iter().filter(|&&b| b).count();
        println!(
            "{set} {i}-{j}: {} + {} features, {} matches, {inliers} inliers, rotation {rot:.3} deg, \
             translation {tr:.3} deg",
            fa.len(),
            fb.len(),
            m.len()
        );
        assert!(inliers >= 250, "{inliers}");
        assert!(rot < 0.3 && tr < 1.0, "{set} {i}-{j}: {rot} {tr}");
    }
}
