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
