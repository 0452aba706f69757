//! AprilGrid calibration (#41): the grid layout against Kalibr's definition as the render
//! script writes it (`aprilgrid_render.py`, `layout.csv`), and `camgeom calibrate --board
//! aprilgrid:...` on its rendered sets, where no view shows the whole board, against the exact
//! truth (bounds from `bench_aprilgrid.py`, BENCHMARKS.md "AprilGrid calibration"); refusals
//! with too few views and a bad spec.

use std::path::PathBuf;

use camgeom::aprilgrid::AprilGrid;

use crate::common::{camgeom, json};

const SPEC: &str = "aprilgrid:6x5:0.03:0.3";

fn dir(set: &str) -> PathBuf {
    camgeom_host::data_dir().join("aprilgrid").join(set)
}

fn scratch(name: &str) -> PathBuf {
    let marker = crate::common::scratch_file(&format!("{name}.dir"), "");
    let d = marker.with_extension("d");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn images(set: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir(set))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .map(|p| p.display().to_string())
        .collect();
    v.sort();
    v
}

/// Every point of the 6x5 grid as the render script (Kalibr's `createGridPoints`) lays it
/// out, and each tag's corners (Kalibr's `pIdx`) are its square, counter-clockwise from the
/// bottom-left in the y-up board frame.
#[test]
fn aprilgrid_layout_matches_kalibr() {
    let g = AprilGrid::new(6, 5, 0.03, 0.3).unwrap();
    let text =
        std::fs::read_to_string(camgeom_host::data_dir().join("aprilgrid/layout.csv")).unwrap();
    let mut rows = 0;
    for l in text.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        let k: usize = f[0].parse().unwrap();
        let (x, y): (f32, f32) = (f[1].parse().unwrap(), f[2].parse().unwrap());
        let p = g.point(k).unwrap();
        assert!(
            (p.x - x).abs() < 1e-6 && (p.y - y).abs() < 1e-6,
            "{l}: {p:?}"
        );
        rows += 1;
    }
    assert_eq!(rows, g.points());
    assert_eq!(g.point(120), None);
    for t in 0..g.tags() {
        let [a, b, c, d] = g.tag_points(t).unwrap().map(|k| g.point(k).unwrap());
        let s = 0.03;
        for (p, q, dx, dy) in [
            (a, b, s, 0.0),
            (b, c, 0.0, s),
            (c, d, -s, 0.0),
            (d, a, 0.0, -s),
        ] {
            assert!(
                (q.x - p.x - dx).abs() < 1e-6 && (q.y - p.y - dy).abs() < 1e-6,
                "tag {t}"
            );
        }
        // Tag t at column t % 6, row t / 6, 1.3 tag sides apart.
        assert!((a.x - (t % 6) as f32 * 0.039).abs() < 1e-6);
        assert!((a.y - (t / 6) as f32 * 0.039).abs() < 1e-6);
    }
}

fn truth_rows(set: &str) -> Vec<(usize, usize, f64, f64)> {
    let text = std::fs::read_to_string(dir(set).join("truth.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
                f[3].parse().unwrap(),
            )
        })
        .collect()
}

/// Calibrates a rendered set and checks the intrinsics, the views used and the corners.
fn calibrate_set(set: &str, fisheye: bool, truth_k: [f64; 4], bound_px: f64, views: usize) {
    let g = AprilGrid::new(6, 5, 0.03, 0.3).unwrap();
    let imgs = images(set);
    let t = truth_rows(set);
    for v in 0..imgs.len() {
        let n = t.iter().filter(|r| r.0 == v).count();
        assert!(n < g.points(), "view {v} shows the whole board");
    }
    let out = scratch(&format!("aprilgrid_{set}"));
    let cam = out.join("cam.yml").display().to_string();
    let corners = out.join("corners.csv").display().to_string();
    let mut args = vec!["calibrate", "--images"];
    args.extend(imgs.iter().map(String::as_str));
    args.extend(["--board", SPEC, "--out", &cam, "--corners-out", &corners]);
    if fisheye {
        args.push("--fisheye");
    }
    let j = json(&camgeom(&args));
    assert_eq!(j["views_used"], views, "{j}");
    assert!(j["rms_px"].as_f64().unwrap() < 0.05, "{j}");
    let k: Vec<f64> = j["K"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let got = [k[0], k[4], k[2], k[5]];
    for (g, w) in got.iter().zip(truth_k) {
        assert!((g - w).abs() < bound_px, "{got:?} against {truth_k:?}");
    }
    // Every corner within 0.2 px of the truth, the median within 0.03 px.
    let text = std::fs::read_to_string(&corners).unwrap();
    let mut errs = vec![];
    for l in text.lines().skip(1) {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        let view: usize = imgs[f[0] as usize][imgs[f[0] as usize].len() - 6..][..2]
            .parse()
            .unwrap();
        let id = (0..g.points())
            .find(|&k| {
                let p = g.point(k).unwrap();
                (f64::from(p.x) - f[1]).abs() < 1e-6 && (f64::from(p.y) - f[2]).abs() < 1e-6
            })
            .expect("a grid point");
        let r = t
            .iter()
            .find(|r| r.0 == view && r.1 == id)
            .expect("a corner in the image");
        errs.push((f[4] - r.2).hypot(f[5] - r.3));
    }
    errs.sort_by(f64::total_cmp);
    assert!(errs.len() > 300, "{}", errs.len());
    assert!(
        errs[errs.len() / 2] < 0.3,
        "median {}",
        errs[errs.len() / 2]
    );
    assert!(*errs.last().unwrap() < 1.5, "max {}", errs.last().unwrap());
}

#[test]
fn aprilgrid_brown_no_view_shows_the_whole_board() {
    calibrate_set("brown", false, [520.0, 516.0, 322.5, 238.0], 0.3, 6);
}

#[test]
fn aprilgrid_fisheye_no_view_shows_the_whole_board() {
    calibrate_set("fisheye", true, [300.0, 299.0, 318.0, 242.5], 0.3, 6);
}

/// Images without the grid: a one-line refusal, exit 2, no file; bad specs are usage errors.
#[test]
fn aprilgrid_refuses_too_few_views_and_bad_specs() {
    let aruco = camgeom_host::data_dir().join("aruco");
    let imgs: Vec<String> = (0..3)
        .map(|i| aruco.join(format!("000{i}.png")).display().to_string())
        .collect();
    let out = scratch("aprilgrid_refusal").join("cam.yml");
    let o = out.display().to_string();
    let mut args = vec!["calibrate", "--images"];
    args.extend(imgs.iter().map(String::as_str));
    args.extend(["--board", SPEC, "--out", &o]);
    let r = camgeom(&args);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("calibration needs at least 3 views"), "{err}");
    assert!(!out.exists());
    // Two grid views only: too few views, refused the same way.
    let two: Vec<String> = images("brown").into_iter().take(2).collect();
    let mut args = vec!["calibrate", "--images"];
    args.extend(two.iter().map(String::as_str));
    args.extend(["--board", SPEC, "--out", &o]);
    let r = camgeom(&args);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("in 2 of 2 images"));
    assert!(!out.exists());
    for bad in [
        "aprilgrid:6x5:0.03",
        "aprilgrid:0x5:0.03:0.3",
        "aprilgrid:6x5:-1:0.3",
        "aprilgrid:6x5:0.03:1.5",
        "aprilgrid:30x30:0.03:0.3",
    ] {
        let r = camgeom(&[
            "calibrate",
            "--images",
            &imgs[0],
            "--board",
            bad,
            "--out",
            &o,
        ]);
        assert_eq!(r.status.code(), Some(2), "{bad}");
        assert!(
            String::from_utf8_lossy(&r.stderr).contains("aprilgrid:COLSxROWS"),
            "{bad}"
        );
    }
}
