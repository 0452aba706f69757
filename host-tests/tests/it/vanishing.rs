//! `camgeom vanishing` against scenes projected by OpenCV (`fixtures/vanishing/`, made by
//! `host-tests/scripts/make_vanishing_fixtures.py`: box and building edges along three
//! orthogonal axes through `cv2.projectPoints`, 0.5 px noise, random outlier segments): the
//! points' camera directions against `R eᵢ`, the horizon's roll against the truth's, a
//! vertical point that is ideal, no horizon from one direction without K (a reason instead),
//! and input errors.

use std::path::PathBuf;
use std::process::Output;

use crate::common::{camgeom, scratch_file};
use serde_json::Value;

/// Largest angle, degrees, between a found point's camera direction `K⁻¹ v` and the true
/// axis direction `R eᵢ` (0.5 px noise on segments of 12..270 px; measured: see the asserts'
/// messages with `--nocapture`).
const DIRECTION_TOLERANCE_DEG: f64 = 1.0;
/// Largest difference between the found and the true horizon's roll, degrees.
const ROLL_TOLERANCE_DEG: f64 = 0.5;

fn dir() -> PathBuf {
    camgeom_host::data_dir().join("fixtures").join("vanishing")
}

fn path(name: &str) -> String {
    dir().join(name).to_str().unwrap().to_string()
}

fn truth(scene: &str) -> Value {
    let text = std::fs::read_to_string(dir().join(format!("{scene}_truth.json"))).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn vanishing(segments: &str, extra: &[&str]) -> Output {
    let mut args = vec!["vanishing", "--segments", segments];
    args.extend_from_slice(extra);
    camgeom(&args)
}

fn json(out: &Output) -> Value {
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    assert!(out.stderr.is_empty(), "{out:?}");
    serde_json::from_slice(&out.stdout).unwrap()
}

fn vec3(v: &Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    core::array::from_fn(|i| a[i].as_f64().unwrap())
}

/// `acos |a · b|` of unit vectors, degrees.
fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let dot: f64 = a.iter().zip(&b).map(|(p, q)| p * q).sum();
    dot.abs().min(1.0).acos().to_degrees()
}

/// `K⁻¹ h` normalised, with the truth's `K` (fx = fy, no skew).
fn camera_direction(k: &[f64], h: [f64; 3]) -> [f64; 3] {
    let (f, cx, cy) = (k[0], k[2], k[5]);
    let d = [(h[0] - cx * h[2]) / f, (h[1] - cy * h[2]) / f, h[2]];
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|x| x / n)
}

/// Each found point matched to the true axis nearest in direction: `(axis, angle)` per point,
/// every axis at most once.
fn match_axes(found: &Value, truth: &Value) -> Vec<(usize, f64)> {
    let k: Vec<f64> = truth["K"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let axes: Vec<[f64; 3]> = truth["vanishing_points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| vec3(&p["direction_camera"]))
        .collect();
    let mut used = [false; 3];
    found["vanishing_points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let d = camera_direction(&k, vec3(&p["h"]));
            let (axis, angle) = axes
                .iter()
                .enumerate()
                .map(|(i, a)| (i, angle_deg(d, *a)))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap();
            assert!(!used[axis], "two points matched axis {axis}: {found}");
            used[axis] = true;
            (axis, angle)
        })
        .collect()
}

fn roll_error(found: &Value, truth: &Value) -> f64 {
    let a = found["horizon"]["roll_deg"].as_f64().unwrap();
    let b = truth["horizon"]["roll_deg"].as_f64().unwrap();
    (a - b).abs()
}

/// The building: three finite points within the tolerance of the true directions, with and
/// without K; the horizon from two horizontal points (without K) and its roll; with K the
/// camera directions and their angles (near 90°); labels and the overlay written.
#[test]
fn building_three_points_and_the_horizon() {
    let t = truth("building");
    let labels = scratch_file("building_labels.csv", "");
    let overlay = scratch_file("building_overlay.png", "");
    let v = json(&vanishing(
        &path("building.csv"),
        &[
            "--intrinsics",
            &path("camera.json"),
            "--labels-out",
            labels.to_str().unwrap(),
            "--overlay",
            overlay.to_str().unwrap(),
        ],
    ));
    assert_eq!(v["segments"], t["segments"]);
    let points = v["vanishing_points"].as_array().unwrap();
    assert_eq!(points.len(), 3, "{v}");
    let matched = match_axes(&v, &t);
    for ((axis, angle), p) in matched.iter().zip(points) {
        eprintln!(
            "building, axis {axis}: {angle:.3}° from R e_{axis}, {} segments, rms {:.3} px",
            p["segments"], p["rms_px"]
        );
        assert!(*angle < DIRECTION_TOLERANCE_DEG, "axis {axis}: {angle}°");
        assert_eq!(p["group"], *axis as i64, "{p}");
        assert!(p["group_share"].as_f64().unwrap() > 0.75, "{p}");
        assert_eq!(p["vertical"], *axis == 1, "{p}");
        assert_eq!(p["ideal"], false);
        // The CLI's own camera direction is K⁻¹ v of the same point.
        let d = camera_direction(&[700.0, 0.0, 322.5, 0.0, 700.0, 236.0], vec3(&p["h"]));
        assert!(angle_deg(d, vec3(&p["direction_camera"])) < 1e-9);
    }
    for a in v["angles_deg"].as_array().unwrap() {
        let deg = a["deg"].as_f64().unwrap();
        assert!((deg - 90.0).abs() < 2.0 * DIRECTION_TOLERANCE_DEG, "{a}");
    }
    // With K the points give the horizon both ways; the core prefers two horizontal points.
    assert_eq!(v["horizon"]["from"], "two_horizontal", "{v}");
    let roll = roll_error(&v, &t);
    eprintln!("building horizon: roll off by {roll:.3}°");
    assert!(roll < ROLL_TOLERANCE_DEG, "{}", v["horizon"]);
    assert!(v["horizon_reason"].is_null());
    // One label per segment, -1 or a point's index; the outliers mostly unassigned.
    let text = std::fs::read_to_string(&labels).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("segment,label"));
    let labels: Vec<i64> = lines
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(labels.len() as u64, t["segments"].as_u64().unwrap());
    assert!(labels.iter().all(|&l| (-1..3).contains(&l)));
    let img = image::open(&overlay).unwrap();
    assert_eq!((img.width(), img.height()), (640, 480));

    // Without K: the same points (no camera directions), the horizon from the two
    // horizontal ones.
    let v = json(&vanishing(&path("building.csv"), &[]));
    assert!(v.get("angles_deg").is_none());
    for ((axis, angle), p) in match_axes(&v, &t)
        .iter()
        .zip(v["vanishing_points"].as_array().unwrap())
    {
        assert!(*angle < DIRECTION_TOLERANCE_DEG, "axis {axis}: {angle}°");
        assert!(p.get("direction_camera").is_none());
    }
    assert_eq!(v["horizon"]["from"], "two_horizontal");
    assert!(roll_error(&v, &t) < ROLL_TOLERANCE_DEG, "{}", v["horizon"]);
}

/// The level camera: the vertical edges are parallel in the image. Their point comes out
/// ideal or so far that only its direction means anything: that direction within the
/// tolerance of the truth, its image direction that of the true ideal point, and the
/// horizon (two horizontal points) through the principal point with the camera's roll.
#[test]
fn level_camera_vertical_point_at_infinity() {
    let t = truth("level");
    assert_eq!(t["vanishing_points"][1]["ideal"], true);
    let v = json(&vanishing(&path("level.csv"), &[]));
    let points = v["vanishing_points"].as_array().unwrap();
    assert_eq!(points.len(), 3, "{v}");
    let matched = match_axes(&v, &t);
    for ((axis, angle), p) in matched.iter().zip(points) {
        eprintln!("level, axis {axis}: {angle:.3}° from R e_{axis}");
        assert!(*angle < DIRECTION_TOLERANCE_DEG, "axis {axis}: {angle}°");
        if *axis == 1 {
            assert_eq!(p["vertical"], true);
            let h = vec3(&p["h"]);
            // Beyond 100 image widths from the centre, or ideal.
            assert!(
                p["ideal"] == true || h[2].abs() * 100.0 * 640.0 < 1.0,
                "not near infinity: {p}"
            );
            // The image direction, as a line's (mod 180°).
            let th = vec3(&t["vanishing_points"][1]["h"]);
            let truth_deg = th[1].atan2(th[0]).to_degrees();
            let diff = (p["direction_deg"].as_f64().unwrap() - truth_deg).rem_euclid(180.0);
            assert!(diff.min(180.0 - diff) < 0.5, "{p} vs {truth_deg}°");
        }
    }
    assert_eq!(v["horizon"]["from"], "two_horizontal");
    let roll = roll_error(&v, &t);
    eprintln!("level horizon: roll off by {roll:.3}°");
    assert!(roll < ROLL_TOLERANCE_DEG, "{}", v["horizon"]);
    // Pitch 0: the horizon passes through the principal point (322.5, 236).
    let l = vec3(&v["horizon"]["line"]);
    let d = l[0] * 322.5 + l[1] * 236.0 + l[2];
    assert!(d.abs() < 5.0, "{d} px from the principal point");
}

/// Exactly parallel segments make an ideal point: `x`, `y` null, `ideal` true, the direction
/// of the lines (vertical: 90°).
#[test]
fn exactly_parallel_segments_give_an_ideal_point() {
    let mut csv = String::from("x1,y1,x2,y2\n");
    for k in 0..10 {
        let x = 20.0 + 31.0 * k as f64;
        csv.push_str(&format!("{x},{},{x},{}\n", 40 + 3 * k, 200 + 7 * k));
    }
    let v = json(&vanishing(
        scratch_file("parallel.csv", &csv).to_str().unwrap(),
        &[],
    ));
    let p = &v["vanishing_points"][0];
    assert_eq!(p["ideal"], true, "{v}");
    assert!(p["x"].is_null() && p["y"].is_null());
    assert_eq!(p["vertical"], true);
    assert!(
        (p["direction_deg"].as_f64().unwrap().abs() - 90.0).abs() < 1e-9,
        "{p}"
    );
    assert!(v["horizon"].is_null());
    assert!(
        v["horizon_reason"]
            .as_str()
            .unwrap()
            .contains("--intrinsics")
    );
}

/// Only the building's vertical segments: one (vertical) point. Without K the horizon is not
/// determined, and the JSON says why instead of guessing; with K it is the polar of the
/// vertical point, with the true roll.
#[test]
fn one_direction_needs_the_camera_for_a_horizon() {
    let t = truth("building");
    let text = std::fs::read_to_string(dir().join("building.csv")).unwrap();
    let mut csv = String::from("x1,y1,x2,y2,group\n");
    for l in text.lines().skip(1).filter(|l| l.ends_with(",1")) {
        csv.push_str(l);
        csv.push('\n');
    }
    let file = scratch_file("vertical.csv", &csv);
    let v = json(&vanishing(file.to_str().unwrap(), &[]));
    let points = v["vanishing_points"].as_array().unwrap();
    assert_eq!(points.len(), 1, "{v}");
    assert_eq!(points[0]["vertical"], true);
    assert!(v["horizon"].is_null(), "{v}");
    let reason = v["horizon_reason"].as_str().unwrap();
    assert!(reason.contains("--intrinsics"), "{reason}");

    let v = json(&vanishing(
        file.to_str().unwrap(),
        &["--intrinsics", &path("camera.json")],
    ));
    assert_eq!(v["horizon"]["from"], "vertical_and_camera", "{v}");
    let roll = roll_error(&v, &t);
    eprintln!("vertical point and K: roll off by {roll:.3}°");
    assert!(roll < ROLL_TOLERANCE_DEG, "{}", v["horizon"]);
    assert!(v["angles_deg"].as_array().unwrap().is_empty());
}

/// Segments that share no point: an empty list and a reason, status 0.
#[test]
fn no_vanishing_point_is_an_answer() {
    let text = std::fs::read_to_string(dir().join("building.csv")).unwrap();
    let mut csv = String::from("x1,y1,x2,y2,group\n");
    for l in text.lines().skip(1).filter(|l| l.ends_with(",-1")) {
        csv.push_str(l);
        csv.push('\n');
    }
    let v = json(&vanishing(
        scratch_file("outliers.csv", &csv).to_str().unwrap(),
        &[],
    ));
    assert_eq!(v["vanishing_points"].as_array().unwrap().len(), 0, "{v}");
    assert!(v["horizon"].is_null());
    let reason = v["horizon_reason"].as_str().unwrap();
    assert!(reason.starts_with("no vanishing point"), "{reason}");
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

#[test]
fn malformed_input_is_a_typed_error() {
    let rows = "0,0,10,10\n".repeat(10);
    let bad = |name: &str, text: &str| scratch_file(name, text).to_str().unwrap().to_string();
    let short_row = format!("{rows}1,2,3\n");
    assert_input_error(
        &vanishing(&bad("short.csv", &short_row), &[]),
        "expected 4 comma-separated numbers",
    );
    assert_input_error(
        &vanishing(&bad("nan.csv", "x1,y1,x2,y2\n1,2,a,4\n"), &[]),
        "x2 is not a number",
    );
    assert_input_error(
        &vanishing(&bad("group.csv", "1,2,3,4,0.5\n"), &[]),
        "group must be an integer",
    );
    assert_input_error(
        &vanishing(&bad("few.csv", "0,0,10,10\n0,5,10,15\n0,9,10,20\n"), &[]),
        "fewer than --min-segments",
    );
    assert_input_error(&vanishing(&path("no-such-file.csv"), &[]), "cannot read");
    assert_input_error(
        &vanishing(&bad("ok.csv", &rows), &["--max-points", "0"]),
        "max_points",
    );
    assert_input_error(
        &vanishing(&bad("ok.csv", &rows), &["--threshold=-1"]),
        "threshold",
    );
}
