//! ArUco markers (OpenCV's predefined dictionaries) in camgeom's quad pipeline: OpenCV-rendered
//! frames with exact corners and OpenCV's own detections (`host-tests/data/aruco/`, made by
//! `host-tests/scripts/aruco_render.py test`), the quiet zone, tag-free real frames, and bad
//! input.

use std::collections::BTreeMap;

use camgeom::apriltag::{Detection, Detector, DetectorConfig, Family, Workspace320x240, families};
use camgeom_host::images::load_gray;
use serde_json::Value;

use crate::cli::assert_usage_error;
use crate::common::camgeom;

fn data(name: &str) -> std::path::PathBuf {
    camgeom_host::data_dir().join("aruco").join(name)
}

/// A CSV of the folder as rows of named fields.
fn csv(name: &str) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(data(name)).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

type Corners = [[f64; 2]; 4];

fn corners_of(r: &BTreeMap<String, String>) -> Corners {
    let v = |k: String| r[&k].parse::<f64>().unwrap();
    std::array::from_fn(|i| [v(format!("x{i}")), v(format!("y{i}"))])
}

/// A truth row: frame, dictionary, sweep, id, side, corners (OpenCV's order).
struct Marker {
    image: String,
    dict: String,
    sweep: String,
    id: u16,
    side: f64,
    corners: Corners,
}

fn truth() -> Vec<Marker> {
    csv("truth.csv")
        .iter()
        .map(|r| Marker {
            image: r["image"].clone(),
            dict: r["dictionary"].clone(),
            sweep: r["sweep"].clone(),
            id: r["id"].parse().unwrap(),
            side: r["side_px"].parse().unwrap(),
            corners: corners_of(r),
        })
        .collect()
}

/// OpenCV's detections per frame: (id, corners in its order).
fn opencv() -> BTreeMap<String, Vec<(u16, Corners)>> {
    let mut out: BTreeMap<String, Vec<(u16, Corners)>> = BTreeMap::new();
    for r in csv("opencv.csv") {
        out.entry(r["image"].clone())
            .or_default()
            .push((r["id"].parse().unwrap(), corners_of(&r)));
    }
    out
}

/// Distances of corresponding corners, `b` read from corner `shift` on.
fn errors(a: &Corners, b: &Corners, shift: usize) -> [f64; 4] {
    std::array::from_fn(|i| {
        let q = b[(i + shift) % 4];
        (a[i][0] - q[0]).hypot(a[i][1] - q[1])
    })
}

/// The marker's corner order is its own (not a marker equal to its own half turn, which is
/// DICT_ARUCO_ORIGINAL's 1023 alone: make_aruco_dictionaries.py lists them).
fn shifts(dict: &str, id: u16) -> &'static [usize] {
    if dict == "DICT_ARUCO_ORIGINAL" && id == 1023 {
        &[0, 2]
    } else {
        &[0]
    }
}

/// The corner errors of `c` against `m` when `c` is `m` (same order, each corner within a
/// quarter of the side and at least 2 px).
fn hit(m: &Marker, id: u16, c: &Corners) -> Option<[f64; 4]> {
    let tol = (m.side / 4.0).max(2.0);
    if id != m.id {
        return None;
    }
    shifts(&m.dict, m.id)
        .iter()
        .map(|&s| errors(&m.corners, c, s))
        .find(|e| e.iter().all(|&x| x <= tol))
}

fn aruco_corners(d: &Detection) -> Corners {
    d.aruco_corners().map(|p| [f64::from(p.x), f64::from(p.y)])
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Every rendered marker of the six frames (six dictionaries, side 10 to 48 px, tilt up to
/// 70 deg), on the board's 320x240 workspace with OpenCV's default parameters: camgeom finds
/// at least the markers OpenCV's ArucoDetector finds, nothing else, every one of OpenCV's with
/// its id and its corners in its order (corner i within a quarter side of OpenCV's), and its
/// corners at least as close to the truth (median over the markers both find; largest error
/// under 1 px).
#[test]
fn aruco_rendered_frames_match_opencv_ids_and_corner_order_and_the_truth() {
    let truth = truth();
    let cv = opencv();
    let mut ws = Box::new(Workspace320x240::new());
    let (mut ours, mut theirs, mut false_ours) = (0, 0, Vec::new());
    let (mut e_ours, mut e_theirs) = (Vec::new(), Vec::new());
    let mut frames: Vec<&str> = truth
        .iter()
        .filter(|m| m.sweep == "grid")
        .map(|m| m.image.as_str())
        .collect();
    frames.dedup();
    assert_eq!(frames.len(), 6);
    for image in frames {
        let markers: Vec<&Marker> = truth.iter().filter(|m| m.image == image).collect();
        let family = families::by_name(&markers[0].dict).unwrap();
        let det = Detector::new(DetectorConfig::default(), &[family]).unwrap();
        let img = load_gray(data(image)).unwrap();
        let found: camgeom::heapless::Vec<Detection, 16> = det
            .detect(&img.view().unwrap(), &mut ws.as_mut_view())
            .unwrap();
        let theirs_here = cv.get(image).cloned().unwrap_or_default();
        // OpenCV's detections: each is camgeom's too, same id, same corner order (corner i
        // within a quarter of the side, at least 2 px, of OpenCV's corner i: OpenCV's
        // unrefined corners are whole pixels, off by up to a pixel or two at steep tilts).
        for (id, c) in &theirs_here {
            let side = (0..4)
                .map(|i| (c[i][0] - c[(i + 1) % 4][0]).hypot(c[i][1] - c[(i + 1) % 4][1]))
                .sum::<f64>()
                / 4.0;
            let tol = (side / 4.0).max(2.0);
            let same = found.iter().any(|d| {
                d.id == *id
                    && shifts(&markers[0].dict, *id)
                        .iter()
                        .any(|&s| errors(c, &aruco_corners(d), s).iter().all(|&e| e < tol))
            });
            let ours: Vec<(u16, Corners)> =
                found.iter().map(|d| (d.id, aruco_corners(d))).collect();
            assert!(
                same,
                "{image}: OpenCV's id {id} at {c:?} not found: {ours:?}"
            );
        }
        for d in &found {
            let c = aruco_corners(d);
            let Some(m) = markers.iter().find(|m| hit(m, d.id, &c).is_some()) else {
                false_ours.push(format!("{image}: id {} at {c:?}", d.id));
                continue;
            };
            ours += 1;
            let e = hit(m, d.id, &c).unwrap();
            if let Some((_, t)) = theirs_here.iter().find(|(id, t)| hit(m, *id, t).is_some()) {
                e_ours.extend(e);
                e_theirs.extend(hit(m, m.id, t).unwrap());
            }
        }
        theirs += theirs_here
            .iter()
            .filter(|(id, t)| markers.iter().any(|m| hit(m, *id, t).is_some()))
            .count();
    }
    let (mo, mt) = (median(&mut e_ours), median(&mut e_theirs));
    let worst = e_ours.iter().copied().fold(0.0, f64::max);
    println!(
        "detected: camgeom {ours}, OpenCV {theirs} of 36; on the {} both find, corner error \
         median camgeom {mo:.3} px, OpenCV {mt:.3} px; camgeom's largest {worst:.3} px",
        e_ours.len() / 4
    );
    assert!(false_ours.is_empty(), "{false_ours:#?}");
    assert!(ours >= theirs, "camgeom {ours} < OpenCV {theirs}");
    assert!(mo <= mt, "corner error camgeom {mo} > OpenCV {mt}");
    assert!(worst < 1.0, "largest corner error {worst}");
}

/// A 1-cell black border marker needs a white quiet zone around it: on a dark surround,
/// DICT_4X4_50 markers with a quiet zone of 1 and 0.5 cells are found with their corners
/// (camgeom's white model is read half a cell outside the border), and one with no quiet zone
/// is found by neither camgeom nor OpenCV (its border joins the surround: no quad). A
/// quarter-cell quiet zone, which OpenCV still finds, camgeom does not (its white samples fall
/// on the dark surround and the border reads as no tag).
#[test]
fn aruco_marker_without_a_quiet_zone_is_not_detected() {
    let truth = truth();
    let cv = opencv();
    let det = Detector::new(DetectorConfig::default(), &[&families::DICT_4X4_50]).unwrap();
    let mut ws = Box::new(Workspace320x240::new());
    let img = load_gray(data("quiet.png")).unwrap();
    let found: camgeom::heapless::Vec<Detection, 8> = det
        .detect(&img.view().unwrap(), &mut ws.as_mut_view())
        .unwrap();
    let theirs = cv.get("quiet.png").cloned().unwrap_or_default();
    let mut seen = BTreeMap::new();
    for m in truth.iter().filter(|m| m.image == "quiet.png") {
        let ours = found
            .iter()
            .any(|d| hit(m, d.id, &aruco_corners(d)).is_some());
        let cv = theirs.iter().any(|(id, c)| hit(m, *id, c).is_some());
        seen.insert(m.sweep.clone(), (ours, cv));
    }
    println!("quiet zone (cells): (camgeom, OpenCV) {seen:?}");
    assert_eq!(found.len(), seen.values().filter(|s| s.0).count());
    assert_eq!(seen["quiet_1.0"], (true, true));
    assert_eq!(seen["quiet_0.5"], (true, true));
    assert_eq!(seen["quiet_0.25"], (false, true));
    assert_eq!(seen["quiet_0.0"], (false, false));
}

/// The tag-free frames of the AprilTag check (the box and tree sequences, the chessboard
/// views): no ArUco marker of any dictionary at OpenCV's default correction. Three detectors
/// cover all 18 dictionaries: at the defaults each of the others is a prefix of one of these
/// with a bound no larger (DICT_4X4_* 0 bits, DICT_5X5_* 1, DICT_6X6_50/100/250 3, _1000 2,
/// DICT_7X7_50 5, _100/_250 4, _1000 3, DICT_ARUCO_ORIGINAL 0, DICT_ARUCO_MIP_36h12 3).
#[test]
fn no_aruco_false_positives_on_tag_free_images() {
    let sets: [&[&'static Family]; 3] = [
        &[
            &families::DICT_4X4_1000,
            &families::DICT_5X5_1000,
            &families::DICT_6X6_250,
            &families::DICT_6X6_1000,
        ],
        &[
            &families::DICT_7X7_50,
            &families::DICT_7X7_250,
            &families::DICT_7X7_1000,
            &families::DICT_ARUCO_ORIGINAL,
        ],
        &[&families::DICT_ARUCO_MIP_36H12],
    ];
    let dets: Vec<Detector> = sets
        .iter()
        .map(|s| Detector::new(DetectorConfig::default(), s).unwrap())
        .collect();
    let mut ws = Box::new(crate::apriltag::PhotoWorkspace::new());
    let mut false_positives = Vec::new();
    let frames = crate::apriltag::tag_free_frames();
    assert!(frames.len() > 200);
    for (_, p) in &frames {
        let img = load_gray(p).unwrap();
        for det in &dets {
            let found: camgeom::heapless::Vec<Detection, 16> = det
                .detect(&img.view().unwrap(), &mut ws.as_mut_view())
                .unwrap();
            for d in &found {
                false_positives.push(format!(
                    "{}: {} id {} hamming {} margin {:.1}",
                    p.display(),
                    d.family.name(),
                    d.id,
                    d.hamming,
                    d.decision_margin
                ));
            }
        }
    }
    assert!(false_positives.is_empty(), "{false_positives:#?}");
}

/// Bad ArUco settings are typed errors naming the field; OpenCV's rates at their bounds are
/// taken.
#[test]
fn aruco_settings_out_of_range_are_typed_errors() {
    let d = DetectorConfig::default();
    let f: &[&'static Family] = &[&families::DICT_6X6_250];
    for (cfg, field) in [
        (
            DetectorConfig {
                error_correction_rate: 1.5,
                ..d
            },
            "error_correction_rate",
        ),
        (
            DetectorConfig {
                error_correction_rate: f64::NAN,
                ..d
            },
            "error_correction_rate",
        ),
        (
            DetectorConfig {
                max_erroneous_bits_in_border_rate: -0.1,
                ..d
            },
            "max_erroneous_bits_in_border_rate",
        ),
    ] {
        assert_eq!(
            Detector::new(cfg, f).unwrap_err(),
            camgeom::Error::InvalidParameter(field)
        );
    }
    let five: Vec<&'static Family> = families::ARUCO.iter().copied().take(5).collect();
    assert_eq!(
        Detector::new(d, &five).unwrap_err(),
        camgeom::Error::InvalidParameter("families")
    );
    for (e, b) in [(0.0, 0.0), (1.0, 1.0)] {
        let cfg = DetectorConfig {
            error_correction_rate: e,
            max_erroneous_bits_in_border_rate: b,
            ..d
        };
        assert!(Detector::new(cfg, f).is_ok());
    }
}

/// `camgeom apriltag --family DICT_6X6_250` prints the markers of the DICT_6X6_250 frame with
/// OpenCV's ids and corners in OpenCV's order (the same JSON as for AprilTag families); an
/// unknown dictionary is a usage error naming the choices.
#[test]
fn cli_apriltag_takes_opencv_dictionary_names() {
    let truth = truth();
    let image = truth
        .iter()
        .find(|m| m.dict == "DICT_6X6_250")
        .unwrap()
        .image
        .clone();
    let out = camgeom(&[
        "apriltag",
        "--image",
        data(&image).to_str().unwrap(),
        "--family",
        "DICT_6X6_250",
    ]);
    assert!(out.status.success(), "{out:?}");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let dets = v["detections"].as_array().unwrap();
    assert!(dets.len() >= 4, "{v}");
    for d in dets {
        assert_eq!(d["family"], "DICT_6X6_250");
        let id = d["id"].as_u64().unwrap() as u16;
        let c: Corners =
            std::array::from_fn(|i| std::array::from_fn(|j| d["corners"][i][j].as_f64().unwrap()));
        let m = truth.iter().find(|m| m.image == image && m.id == id);
        assert!(m.is_some_and(|m| hit(m, id, &c).is_some()), "{d}");
    }
    let bad = camgeom(&[
        "apriltag",
        "--image",
        data(&image).to_str().unwrap(),
        "--family",
        "DICT_6X6_251",
    ]);
    assert_usage_error(&bad, "DICT_ARUCO_MIP_36h12");
}
