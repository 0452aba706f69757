//! camgeom's SIFT against OpenCV's on the box images (`host-tests/scripts/make_sift_fixtures.py`
//! writes `data/features/sift_box.json`): keypoint positions and scales, descriptors at the
//! keypoints both find, and the matches of box.png in box_in_scene.png.
//!
//! Run with `--nocapture` to see the figures.

use std::path::PathBuf;

use camgeom::features::matching::{
    FloatDescriptor, FloatMatch, MatchConfig, float_scratch_len, match_float_descriptors,
};
use camgeom::features::sift::{self, SiftConfig, SiftFeature, sift_detect};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom_host::images::{GrayImage, load_gray};

fn data(name: &str) -> PathBuf {
    camgeom_host::data_dir().join("features").join(name)
}

fn fixture() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(data("sift_box.json")).unwrap()).unwrap()
}

fn detect(img: &GrayImage, config: &SiftConfig) -> Vec<SiftFeature> {
    let mut scratch =
        vec![0.0; sift::scratch_len(img.width, img.height, config.intervals, config.upsample)];
    let mut out = vec![SiftFeature::default(); 4000];
    let n = sift_detect(
        &img.view().unwrap(),
        &config.check().unwrap(),
        &mut scratch,
        &mut out,
    )
    .unwrap();
    out.truncate(n);
    out
}

/// OpenCV's settings: the image doubled, plain SIFT.
fn opencv_like() -> SiftConfig {
    SiftConfig {
        upsample: true,
        ..SiftConfig::default()
    }
}

#[test]
fn sift_keypoints_and_descriptors_agree_with_opencv() {
    let fx = fixture();
    let scene = load_gray(data("box_in_scene.png")).unwrap();
    let ours = detect(&scene, &opencv_like());
    let total = fx["scene_keypoints"].as_u64().unwrap() as f64;
    // Repeatability: OpenCV's strongest keypoints with one of ours within 1 px and 20 % in
    // scale (OpenCV's size is the diameter, twice our sigma); among those, the descriptors of
    // the one of ours nearest in angle.
    let (mut found, mut distances, mut offsets) = (0, Vec::new(), Vec::new());
    let kps = fx["keypoints"].as_array().unwrap();
    for (k, d) in kps.iter().zip(fx["descriptors"].as_array().unwrap()) {
        let v: Vec<f64> = k
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let (x, y, sigma, angle) = (v[0] as f32, v[1] as f32, v[2] as f32 / 2.0, v[3] as f32);
        let near: Vec<&SiftFeature> = ours
            .iter()
            .filter(|f| {
                (f.keypoint.x - x).hypot(f.keypoint.y - y) < 1.0
                    && (f.keypoint.sigma / sigma - 1.0).abs() < 0.2
            })
            .collect();
        let angle_gap = |f: &SiftFeature| {
            let a = (f.keypoint.angle.to_degrees() - angle).rem_euclid(360.0);
            a.min(360.0 - a)
        };
        let Some(best) = near
            .iter()
            .min_by(|a, b| angle_gap(a).total_cmp(&angle_gap(b)))
        else {
            continue;
        };
        found += 1;
        offsets.push((best.keypoint.x - x).hypot(best.keypoint.y - y));
        if angle_gap(best) < 3.0 {
            let hex = d.as_str().unwrap();
            let mut theirs = [0f32; 128];
            for (i, t) in theirs.iter_mut().enumerate() {
                *t = f32::from(u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap());
            }
            let norm = theirs.iter().map(|t| t * t).sum::<f32>().sqrt();
            let dist = theirs
                .iter()
                .zip(&best.descriptor.0)
                .map(|(t, o)| (t / norm - o).powi(2))
                .sum::<f32>()
                .sqrt();
            distances.push(dist);
        }
    }
    let median = |v: &mut Vec<f32>| {
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let repeat = found as f64 / kps.len() as f64;
    let (md, mo) = (median(&mut distances), median(&mut offsets));
    println!(
        "camgeom {} keypoints, OpenCV {total}; of OpenCV's {} strongest, {found} found \
         (median offset {mo:.3} px); descriptor distance to OpenCV's (unit vectors) median {md:.3} over {}",
        ours.len(),
        kps.len(),
        distances.len()
    );
    assert!((ours.len() as f64 - total).abs() < 0.1 * total);
    assert!(repeat >= 0.95, "repeatability {repeat}");
    assert!(mo < 0.05, "median offset {mo}");
    assert!(
        distances.len() * 10 >= found * 9 && md < 0.03,
        "descriptor distance {md}"
    );
}

#[test]
fn sift_matches_the_box_in_its_scene_as_well_as_opencv() {
    let fx = fixture();
    let h: Vec<f64> = fx["H"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let h = Matrix3::from_row_slice(&h);
    let box_img = load_gray(data("box.png")).unwrap();
    let scene = load_gray(data("box_in_scene.png")).unwrap();
    for (name, config) in [
        ("SIFT", opencv_like()),
        (
            "RootSIFT",
            SiftConfig {
                root: true,
                ..opencv_like()
            },
        ),
    ] {
        let (a, b) = (detect(&box_img, &config), detect(&scene, &config));
        let da: Vec<FloatDescriptor> = a.iter().map(|f| f.descriptor).collect();
        let db: Vec<FloatDescriptor> = b.iter().map(|f| f.descriptor).collect();
        let params = MatchConfig {
            ratio: 0.75,
            cross_check: false,
            max_distance: 256,
        }
        .check()
        .unwrap();
        let mut out = vec![FloatMatch::default(); da.len()];
        let mut scratch = vec![0u32; float_scratch_len(db.len())];
        let n = match_float_descriptors(&da, &db, &params, &mut scratch, &mut out).unwrap();
        let inliers = out[..n]
            .iter()
            .filter(|m| {
                let (p, q) = (&a[m.query as usize].keypoint, &b[m.train as usize].keypoint);
                let x = Point2::new(f64::from(p.x), f64::from(p.y));
                let y = Point2::from_homogeneous(h * x.to_homogeneous()).unwrap();
                (y - Point2::new(f64::from(q.x), f64::from(q.y))).norm() < 3.0
            })
            .count();
        println!(
            "{name}: {n} matches, {inliers} within 3 px of OpenCV's homography (OpenCV: {} and {})",
            fx["matches"], fx["inliers"]
        );
        assert!(inliers as u64 * 10 >= fx["inliers"].as_u64().unwrap() * 9);
        assert!(inliers * 10 >= n * 8);
    }
}
