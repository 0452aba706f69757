//! `camgeom calibrate` and `camgeom undistort` end to end: the 13 bundled views against
//! OpenCV's calibration of them (`fixtures/calib/real_opencv.json`), the camera file read
//! back by OpenCV's `cv2.FileStorage` and by camgeom-host's loader, the undistorted image
//! against OpenCV's `initUndistortRectifyMap` + `remap` (`host-tests/scripts/calib_cli_opencv.py`,
//! run here when python3 with cv2 is installed), and every input error.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use camgeom::camera::Lens;
use camgeom_host::images::{GrayImage, load_gray, save_gray};
use serde_json::Value;

use crate::common::{camgeom, chessboard};

/// A fresh, empty directory for one test's outputs.
fn scratch_dir(name: &str) -> PathBuf {
    let marker = crate::common::scratch_file(&format!("{name}.dir"), "");
    let dir = marker.with_extension("d");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The 13 bundled views, in file-name order.
fn bundled_views() -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(chessboard(""))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with("left") && n.ends_with(".jpg")
        })
        .map(|p| p.display().to_string())
        .collect();
    v.sort();
    assert_eq!(v.len(), 13);
    v
}

fn run_calibrate(images: &[String], extra: &[&str], out: &Path) -> Output {
    let mut args: Vec<&str> = vec!["calibrate", "--images"];
    args.extend(images.iter().map(String::as_str));
    let out = out.display().to_string();
    args.extend(["--board", "9x6", "--square", "25", "--out", &out]);
    args.extend(extra);
    camgeom(&args)
}

fn json(o: &Output) -> Value {
    assert!(
        o.status.success(),
        "camgeom failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The OpenCV helper script, or `None` (with a note on stderr) when python3 or cv2 is absent.
fn opencv() -> Option<Command> {
    let ok = Command::new("python3")
        .args(["-c", "import cv2, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!("skipped: the OpenCV comparison needs python3 with cv2 and numpy");
        return None;
    }
    let mut c = Command::new("python3");
    c.arg(camgeom_host::package_dir().join("scripts/calib_cli_opencv.py"));
    Some(c)
}

/// The file as `cv2.FileStorage` reads it.
fn opencv_read(path: &Path) -> Option<Value> {
    let o = opencv()?.arg("read").arg(path).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    Some(serde_json::from_slice(&o.stdout).unwrap())
}

fn real_opencv() -> Value {
    let path = camgeom_host::data_dir().join("fixtures/calib/real_opencv.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The camera file as camgeom-host's loader reads it: K (9) and the lens coefficients.
fn loaded(path: &Path) -> (Vec<f64>, Vec<f64>, bool) {
    let spec = camgeom_host::load_camera(path).unwrap();
    let k = &spec.camera.intrinsics;
    assert_eq!(spec.image_size, Some((640, 480)));
    let kv = vec![k.fx(), k.skew(), k.cx(), 0.0, k.fy(), k.cy(), 0.0, 0.0, 1.0];
    match spec.camera.lens {
        Lens::KannalaBrandt(f) => (kv, f.to_opencv().to_vec(), true),
        Lens::BrownConrady(d) => (kv, d.to_opencv().to_vec(), false),
    }
}

#[test]
fn calibrates_the_bundled_views_as_well_as_opencv_and_opencv_reads_the_file() {
    let dir = scratch_dir("calib13");
    let out = dir.join("camera.yml");
    let j = json(&run_calibrate(&bundled_views(), &[], &out));
    println!("{}", serde_json::to_string(&j).unwrap());
    assert_eq!(j["views_used"], 13);
    assert_eq!(j["views_rejected"].as_array().unwrap().len(), 0);
    assert!(j["warnings"].as_array().unwrap().is_empty());
    // OpenCV from its own corners (findChessboardCorners + cornerSubPix 5x5, its acceptance
    // test's settings) reaches 0.1962 px; camgeom's corners must do at least as well (no
    // tolerance: the saddle fit measured 0.1690 in docs/notes/calibration.md).
    let cv = &real_opencv()["subpix5"];
    let rms = j["rms_px"].as_f64().unwrap();
    let cv_rms = cv["rms"].as_f64().unwrap();
    println!("rms: camgeom {rms:.4}, OpenCV {cv_rms:.4}");
    assert!(rms <= cv_rms, "{rms} > OpenCV's {cv_rms}");
    // Intrinsics against OpenCV's from its corners: K with OpenCV's own acceptance tolerance
    // (test_calibration.py: |K - K_test|₁ < 10); the two corner sets differ by 0.2 px median,
    // which moves fx by about one standard deviation (0.44 px). The distortion coefficients
    // each within three standard deviations of the difference (both estimates' own, added in
    // quadrature): OpenCV's |d - d_test|₁ < 0.05 is mostly k3, the least determined
    // coefficient (σ 0.075 here), so an L1 bound says little about the others.
    let k = floats(&j["K"]);
    let d = floats(&j["distortion"]);
    let kl1: f64 = k
        .iter()
        .zip(floats(&cv["K"]))
        .map(|(a, b)| (a - b).abs())
        .sum();
    let dl1: f64 = d
        .iter()
        .zip(floats(&cv["dist"]))
        .map(|(a, b)| (a - b).abs())
        .sum();
    println!("|K - K_opencv|₁ {kl1:.3}, |d - d_opencv|₁ {dl1:.4}");
    assert!(kl1 < 10.0, "{kl1}");
    let ours_std = floats(&j["std"]["distortion"]);
    let cv_std = floats(&cv["std_intrinsics"]);
    for (i, (a, b)) in d.iter().zip(floats(&cv["dist"])).enumerate() {
        let sigma = ours_std[i].hypot(cv_std[4 + i]);
        assert!(
            (a - b).abs() < 3.0 * sigma,
            "distortion[{i}]: {a} against OpenCV's {b}, σ {sigma}"
        );
    }
    // Standard deviations of the same order as OpenCV's (fx: 0.38 against 0.44); a factor of
    // two either way would mean a different estimator.
    let sfx = j["std"]["fx"].as_f64().unwrap();
    let cv_sfx = floats(&cv["std_intrinsics"])[0];
    assert!(
        sfx > 0.5 * cv_sfx && sfx < 2.0 * cv_sfx,
        "{sfx} vs {cv_sfx}"
    );
    let per_view = floats(&j["per_view_rms"]);
    assert_eq!(per_view.len(), 13);

    // camgeom-host's loader reads back exactly what was printed.
    let (lk, ld, fisheye) = loaded(&out);
    assert!(!fisheye);
    assert_eq!(lk, k);
    assert_eq!(ld, d);

    // The pictures: a 4-column contact sheet of 13 tiles at half size, one bar per view.
    let sheet = load_gray(dir.join("camera_corners.png")).unwrap();
    assert_eq!(
        (sheet.width, sheet.height),
        (4 * 320 + 5 * 2, 4 * 240 + 5 * 2)
    );
    let chart = load_gray(dir.join("camera_reprojection_errors.png")).unwrap();
    assert!(chart.width > 13 * 24);

    // OpenCV reads the same numbers (written with 17 significant digits: exact).
    let Some(cvf) = opencv_read(&out) else { return };
    assert_eq!(floats(&cvf["K"]), k);
    assert_eq!(floats(&cvf["dist"]), d);
    assert_eq!(cvf["dist_shape"], serde_json::json!([5, 1]));
    assert_eq!(floats(&cvf["per_view"]), per_view);
    assert_eq!(cvf["avg_reprojection_error"].as_f64().unwrap(), rms);
    assert_eq!(
        (cvf["image_width"].clone(), cvf["image_height"].clone()),
        (640.into(), 480.into())
    );
    assert_eq!(
        (cvf["board_width"].clone(), cvf["board_height"].clone()),
        (9.into(), 6.into())
    );
    assert_eq!(cvf["square_size"].as_f64(), Some(25.0));
    assert_eq!(cvf["flags"], 0);
    assert_eq!(cvf["fisheye_model"], 0);
}

#[test]
fn flags_fix_what_they_name_and_are_written_as_opencvs() {
    let dir = scratch_dir("calibflags");
    let out = dir.join("fixed.yaml");
    let j = json(&run_calibrate(
        &bundled_views(),
        &[
            "--fix-aspect",
            "--fix-principal-point",
            "--zero-tangent",
            "--fix-k3",
        ],
        &out,
    ));
    let k = floats(&j["K"]);
    let d = floats(&j["distortion"]);
    assert_eq!(k[0], k[4], "fx = fy");
    // OpenCV's CALIB_FIX_PRINCIPAL_POINT keeps the centre ((w - 1)/2, (h - 1)/2).
    assert_eq!((k[2], k[5]), (319.5, 239.5));
    assert_eq!((d[2], d[3], d[4]), (0.0, 0.0, 0.0));
    let s = floats(&j["std"]["distortion"]);
    assert_eq!((s[2], s[3], s[4]), (0.0, 0.0, 0.0));
    assert_eq!(loaded(&out).0, k);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("aspectRatio: 1."), "{text}");
    // CALIB_FIX_ASPECT_RATIO 2 | FIX_PRINCIPAL_POINT 4 | ZERO_TANGENT_DIST 8 | FIX_K3 128.
    let Some(cvf) = opencv_read(&out) else { return };
    assert_eq!(cvf["flags"], 2 + 4 + 8 + 128);
    assert_eq!(floats(&cvf["K"]), k);
}

#[test]
fn fisheye_files_hold_four_coefficients_that_opencv_and_the_loader_read() {
    let dir = scratch_dir("calibfisheye");
    let out = dir.join("fisheye.yml");
    let j = json(&run_calibrate(&bundled_views(), &["--fisheye"], &out));
    println!("{}", serde_json::to_string(&j).unwrap());
    let k = floats(&j["K"]);
    let d = floats(&j["distortion"]);
    assert_eq!(d.len(), 4);
    assert_eq!(floats(&j["std"]["distortion"]).len(), 4);
    assert_eq!(j["model"], "kannala_brandt");
    // The bundled lens is no fisheye, but the equidistant model with 4 coefficients fits a
    // moderate barrel lens: the RMS stays within 0.1 px of the Brown-Conrady fit's 0.17 px.
    assert!(j["rms_px"].as_f64().unwrap() < 0.3);
    let (lk, ld, fisheye) = loaded(&out);
    assert!(fisheye);
    assert_eq!((lk, ld), (k.clone(), d.clone()));
    // `camgeom camera` converts it to camgeom's JSON form, which reads back the same camera.
    let o = camgeom(&["camera", "--intrinsics", &out.display().to_string()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let as_json = dir.join("fisheye.json");
    std::fs::write(&as_json, &o.stdout).unwrap();
    assert_eq!(
        camgeom_host::load_camera(&as_json).unwrap(),
        camgeom_host::load_camera(&out).unwrap()
    );
    let Some(cvf) = opencv_read(&out) else { return };
    assert_eq!(cvf["fisheye_model"], 1);
    // fisheye::CALIB_RECOMPUTE_EXTRINSIC 1 | CALIB_FIX_SKEW 8: camgeom's fisheye calibration.
    assert_eq!(cvf["flags"], 9);
    assert_eq!(floats(&cvf["K"]), k);
    assert_eq!(floats(&cvf["dist"]), d);
    assert_eq!(cvf["dist_shape"], serde_json::json!([4, 1]));
}

/// A fronto-parallel 9x6 board (10x7 squares of `s` px from `(ox, oy)`) in a 640x480 frame,
/// anti-aliased by 4x4 supersampling.
fn fronto_board(s: f64, ox: f64, oy: f64) -> GrayImage {
    let mut img = GrayImage::filled(640, 480, 0);
    for y in 0..480 {
        for x in 0..640 {
            let mut acc = 0u32;
            for sy in 0..4 {
                for sx in 0..4 {
                    let u = (x as f64 + (sx as f64 + 0.5) / 4.0 - 0.5 - ox) / s;
                    let v = (y as f64 + (sy as f64 + 0.5) / 4.0 - 0.5 - oy) / s;
                    let dark = (0.0..10.0).contains(&u)
                        && (0.0..7.0).contains(&v)
                        && (u.floor() as i64 + v.floor() as i64) % 2 == 0;
                    acc += if dark { 30 } else { 210 };
                }
            }
            img.data[y * 640 + x] = (acc / 16) as u8;
        }
    }
    img
}

/// Runs a failing calibrate: exit 2, one `camgeom: error:` line containing `expect`, and
/// nothing written (neither the camera file nor the pictures).
fn assert_rejected(images: &[String], extra: &[&str], board: &str, square: &str, expect: &str) {
    let dir = scratch_dir("calibbad");
    let out = dir.join("camera.yml");
    let outs = out.display().to_string();
    let mut args: Vec<&str> = vec!["calibrate", "--images"];
    args.extend(images.iter().map(String::as_str));
    args.extend(["--board", board, "--square", square, "--out", &outs]);
    args.extend(extra);
    let o = camgeom(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("camgeom: error: "), "{err}");
    assert!(err.contains(expect), "expected `{expect}` in: {err}");
    assert!(o.stdout.is_empty());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "{err}");
}

#[test]
fn calibrate_rejects_bad_input_and_writes_nothing() {
    let views = bundled_views();
    let rendered = |n: &str| {
        camgeom_host::data_dir()
            .join("fixtures/calib/rendered")
            .join(n)
            .display()
            .to_string()
    };
    let dir = scratch_dir("calibinputs");
    let save = |name: &str, img: &GrayImage| {
        let p = dir.join(name);
        save_gray(img, &p).unwrap();
        p.display().to_string()
    };
    // No board in any image (texture without a chessboard).
    let absent = rendered("absent.png");
    assert_rejected(
        &[absent.clone(), absent.clone(), absent],
        &[],
        "9x6",
        "25",
        "no 9x6 chessboard found in any of the 3 images",
    );
    // Found in 2 of 3 images: the third is blank.
    let blank = save("blank.png", &GrayImage::filled(640, 480, 128));
    assert_rejected(
        &[views[0].clone(), views[1].clone(), blank],
        &[],
        "9x6",
        "25",
        "found in 2 of 3 images; calibration needs at least 3 views (not found in: blank.png)",
    );
    // Four fronto-parallel views (translated and scaled only): the core's degenerate error.
    let fronto: Vec<String> = [
        (40.0, 100.0, 100.0),
        (36.0, 150.0, 140.0),
        (44.0, 90.0, 80.0),
        (30.0, 200.0, 150.0),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(s, x, y))| save(&format!("fronto{i}.png"), &fronto_board(s, x, y)))
    .collect();
    assert_rejected(&fronto, &[], "9x6", "25", "degenerate");
    // Images of another size are skipped with a warning, not rejected: see
    // views_without_the_board_are_listed_and_left_out.
    // Square size.
    for sq in ["0", "-25", "nan", "inf"] {
        assert_rejected(&views, &[], "9x6", sq, "--square must be a positive length");
    }
    // Malformed board sizes, and one with too few corners on a side.
    for b in ["9by6", "9x", "x6", "9x6x2", "-9x6"] {
        assert_rejected(&views, &[], b, "25", "--board: expected COLSxROWS");
    }
    assert_rejected(&views, &[], "2x6", "25", "each side must have 3 to 64");
    // Larger than the detector holds (256 corners).
    assert_rejected(
        &views,
        &[],
        "20x20",
        "25",
        "400 inner corners; the detector holds at most 256",
    );
    // Options that do not go together, and an output that is not YAML.
    assert_rejected(
        &views,
        &["--fisheye", "--zero-tangent"],
        "9x6",
        "25",
        "--zero-tangent",
    );
    assert_rejected(&views, &["--fix-k4"], "9x6", "25", "--fix-k4");
    assert_rejected(&views, &["--fix-aspect", "0"], "9x6", "25", "--fix-aspect");
    // A missing image.
    assert_rejected(
        &[views[0].clone(), "no-such-image.png".into()],
        &[],
        "9x6",
        "25",
        "no-such-image.png: cannot read",
    );
}

#[test]
fn calibrate_refuses_a_camera_file_that_is_not_yaml() {
    let dir = scratch_dir("calibxml");
    let out = dir.join("camera.xml");
    let o = run_calibrate(&bundled_views(), &[], &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("name it .yml or .yaml"));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
}

/// camgeom's undistorted image against OpenCV's from the same PNG.
struct Compared {
    /// camgeom's new camera matrix and OpenCV's (`getOptimalNewCameraMatrix` /
    /// `estimateNewCameraMatrixForUndistortRectify`): largest difference, px.
    dk: f64,
    /// Pixels equal and largest difference against OpenCV's map and remap through camgeom's
    /// new camera matrix (the map and the remap alone).
    same_k: (usize, i32),
    /// The same against OpenCV's whole chain (its own new camera matrix).
    own_k: (usize, i32),
}

fn pixel_diff(a: &Path, b: &Path) -> (usize, i32) {
    let (x, y) = (load_gray(a).unwrap(), load_gray(b).unwrap());
    assert_eq!((x.width, x.height), (y.width, y.height));
    let diffs: Vec<i32> = x
        .data
        .iter()
        .zip(&y.data)
        .map(|(a, b)| (*a as i32 - *b as i32).abs())
        .collect();
    (
        diffs.iter().filter(|d| **d == 0).count(),
        *diffs.iter().max().unwrap(),
    )
}

fn undistort_both(camera: &Path, image: &Path, option: &str, a: f64) -> Option<Compared> {
    let dir = scratch_dir("undist");
    let ours = dir.join("camgeom.png");
    let a_text = a.to_string();
    let j = json(&camgeom(&[
        "undistort",
        "--intrinsics",
        &camera.display().to_string(),
        "--image",
        &image.display().to_string(),
        "--out",
        &ours.display().to_string(),
        option,
        &a_text,
    ]));
    let k = floats(&j["new_camera_matrix"]);
    let mut opencv_k = Vec::new();
    let mut diffs = Vec::new();
    for (name, given) in [
        ("opencv_own.png", None),
        (
            "opencv_same.png",
            Some(format!("{:?},{:?},{:?},{:?}", k[0], k[4], k[2], k[5])),
        ),
    ] {
        let theirs = dir.join(name);
        let mut c = opencv()?;
        c.arg("undistort")
            .arg(camera)
            .arg(image)
            .arg(&a_text)
            .arg(&theirs);
        if let Some(g) = given {
            c.arg(g);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let cv: Value = serde_json::from_slice(&o.stdout).unwrap();
        opencv_k = floats(&cv["K_new"]);
        diffs.push(pixel_diff(&ours, &theirs));
    }
    let dk = k
        .iter()
        .zip(&opencv_k)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!(
        "{option} {a}: new K within {dk:.4} px of OpenCV's; pixels equal to OpenCV's (of 307200), \
         max diff: same K {:?}, OpenCV's own K {:?}",
        diffs[1], diffs[0]
    );
    Some(Compared {
        dk,
        same_k: diffs[1],
        own_k: diffs[0],
    })
}

#[test]
fn undistort_equals_opencvs_initundistortrectifymap_and_remap() {
    // Both read the same lossless PNG (the JPEG decoders could differ by a grey level).
    let dir = scratch_dir("undistsrc");
    let png = dir.join("left01.png");
    save_gray(&load_gray(chessboard("left01.jpg")).unwrap(), &png).unwrap();
    let camera = chessboard("left_intrinsics.yml");
    for a in [0.0, 0.5, 1.0] {
        let Some(c) = undistort_both(&camera, &png, "--alpha", a) else {
            return;
        };
        // getOptimalNewCameraMatrix undistorts its outline points with a few fixed
        // iterations, camgeom's Newton runs to rounding: 0.004 px apart (calibration notes).
        assert!(c.dk < 0.01, "{}", c.dk);
        // Through the same new K, the same Q10.5 map (both in f64) and the same integer
        // remap: every pixel equal (measured 307,200 of 307,200 at each alpha).
        assert_eq!(c.same_k, (307_200, 0));
        // OpenCV's whole chain: its new K is up to 0.004 px off, which moves some map entries
        // by 1/32 px, changing a pixel by at most the image's change over 1/32 px (a
        // full-contrast edge, about 200 grey levels over a pixel, changes by 6); measured
        // 99.4 % equal or more, max 7.
        assert!(c.own_k.0 as f64 >= 0.97 * 307_200.0, "{:?}", c.own_k);
        assert!(c.own_k.1 <= 8, "{:?}", c.own_k);
    }
}

#[test]
fn undistort_of_a_fisheye_file_equals_opencvs_fisheye_remap() {
    let dir = scratch_dir("undistfish");
    let cam = dir.join("fisheye.yml");
    json(&run_calibrate(&bundled_views(), &["--fisheye"], &cam));
    let png = dir.join("left01.png");
    save_gray(&load_gray(chessboard("left01.jpg")).unwrap(), &png).unwrap();
    for b in [0.0, 0.5, 1.0] {
        let Some(c) = undistort_both(&cam, &png, "--balance", b) else {
            return;
        };
        // estimateNewCameraMatrixForUndistortRectify is up to 0.04 px from camgeom's
        // (calibration notes: OpenCV's fixed iteration count against Newton to rounding).
        assert!(c.dk < 0.05, "{}", c.dk);
        // As for Brown-Conrady: through the same new K, every pixel equal.
        assert_eq!(c.same_k, (307_200, 0));
        // OpenCV's own K: 0.015 px apart at balance 0 moves a third of the entries by
        // 1/32 px (measured 92 % of the pixels equal), never by more than that: one 1/32 px
        // step at the steepest edge possible (255 grey levels a pixel) changes a pixel by at
        // most ⌈255 / 32⌉ = 8, and the interpolation's rounding by one more.
        assert!(c.own_k.0 as f64 >= 0.85 * 307_200.0, "{:?}", c.own_k);
        assert!(c.own_k.1 <= 9, "{:?}", c.own_k);
    }
}

/// The bundled 640x480 camera on a `w x h` frame: a 4:3 sensor of width `w` cropped to `h`
/// (`scaled_camera` of `undistort_peers.py`), as an OpenCV camera file.
fn scaled_camera_file(dir: &Path, w: usize, h: usize) -> PathBuf {
    let k = &crate::common::bundled_camera().camera;
    let s = w as f64 / 640.0;
    let (fx, fy) = (k.intrinsics.fx() * s, k.intrinsics.fy() * s);
    let cx = (k.intrinsics.cx() + 0.5) * s - 0.5;
    let cy = (k.intrinsics.cy() + 0.5) * s - 0.5 - (480.0 * s - h as f64) / 2.0;
    let d = k.lens.coefficients();
    let path = dir.join(format!("camera_{w}x{h}.yml"));
    std::fs::write(
        &path,
        format!(
            "%YAML:1.0\n---\nimage_width: {w}\nimage_height: {h}\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {fx:?}, 0., {cx:?}, 0., {fy:?}, {cy:?}, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ {:?}, {:?}, {:?}, {:?}, {:?} ]\n",
            d[0], d[1], d[2], d[3], d[4]
        ),
    )
    .unwrap();
    path
}

#[test]
fn undistort_of_a_1920x1080_colour_frame_equals_opencvs_and_grey_stays_grey() {
    let dir = scratch_dir("undistbig");
    let (w, h) = (1920usize, 1080usize);
    let camera = scaled_camera_file(&dir, w, h);
    // A deterministic colour frame: checks of three periods, a ramp per channel.
    let rgb = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let c = |p: usize, k: usize| ((((x / p + y / p) % 2) * 150 + (k * x + y) % 97) % 256) as u8;
        image::Rgb([c(9, 1), c(14, 3), c(23, 2)])
    });
    let colour = dir.join("colour.png");
    rgb.save(&colour).unwrap();
    let grey = dir.join("grey.png");
    save_gray(&camgeom_host::images::gray_of_rgb(&rgb), &grey).unwrap();
    for (src, channels) in [(&colour, 3u64), (&grey, 1)] {
        let ours = dir.join(format!("camgeom_{channels}.png"));
        let j = json(&camgeom(&[
            "undistort",
            "--intrinsics",
            &camera.display().to_string(),
            "--image",
            &src.display().to_string(),
            "--out",
            &ours.display().to_string(),
        ]));
        assert_eq!(j["channels"], channels);
        assert_eq!(
            (j["width"].as_u64(), j["height"].as_u64()),
            (Some(1920), Some(1080))
        );
        let out = image::open(&ours).unwrap();
        assert_eq!(out.color().channel_count() as u64, channels);
        // OpenCV through camgeom's new camera matrix: its map and remap.
        let k = floats(&j["new_camera_matrix"]);
        let theirs = dir.join(format!("opencv_{channels}.png"));
        let Some(mut c) = opencv_undistort_script() else {
            return;
        };
        let o = c
            .arg(&camera)
            .arg(src)
            .arg("0")
            .arg(&theirs)
            .arg(format!("{:?},{:?},{:?},{:?}", k[0], k[4], k[2], k[5]))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let cv = image::open(&theirs).unwrap();
        assert_eq!(cv.color().channel_count() as u64, channels);
        let (a, b) = (out.into_bytes(), cv.into_bytes());
        assert_eq!(a.len(), w * h * channels as usize);
        let equal = a.iter().zip(&b).filter(|(x, y)| x == y).count();
        println!(
            "{w}x{h}, {channels} channel(s): {equal} of {} samples equal to OpenCV's",
            a.len()
        );
        // The same Q.5 map (OpenCV's CV_16SC2 form, both in f64) and the same integer
        // remap: every sample equal (measured).
        assert_eq!(equal, a.len());
    }
}

/// `undistort_peers.py opencv` (OpenCV's undistortion of a grey or colour file), `None` when
/// python3 has no cv2.
fn opencv_undistort_script() -> Option<Command> {
    opencv()?;
    let mut c = Command::new("python3");
    c.arg(camgeom_host::package_dir().join("scripts/undistort_peers.py"))
        .arg("opencv");
    Some(c)
}

#[test]
fn undistort_refuses_frames_beyond_32767_px_and_writes_nothing() {
    let dir = scratch_dir("undisthuge");
    let out = dir.join("out.png");
    for (w, h) in [(32768usize, 1usize), (1, 32768)] {
        let camera = scaled_camera_file(&dir, w, h);
        let img = dir.join("huge.png");
        save_gray(&GrayImage::filled(w, h, 100), &img).unwrap();
        let o = camgeom(&[
            "undistort",
            "--intrinsics",
            &camera.display().to_string(),
            "--image",
            &img.display().to_string(),
            "--out",
            &out.display().to_string(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("at most 32767 pixels each way"), "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn undistort_rejects_bad_input_and_writes_nothing() {
    let dir = scratch_dir("undistbad");
    let out = dir.join("out.png");
    let outs = out.display().to_string();
    let cam = chessboard("left_intrinsics.yml").display().to_string();
    let img = chessboard("left01.jpg").display().to_string();
    let small = camgeom_host::data_dir()
        .join("fixtures/calib/rendered/rot135.png")
        .display()
        .to_string();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--intrinsics", "missing.yml", "--image", &img],
            "missing.yml: cannot read",
        ),
        (
            vec!["--intrinsics", &cam, "--image", "missing.png"],
            "missing.png: cannot read",
        ),
        (
            vec!["--intrinsics", &cam, "--image", &img, "--alpha", "1.5"],
            "--alpha must be in [0, 1]",
        ),
        (
            vec!["--intrinsics", &cam, "--image", &img, "--alpha", "-0.1"],
            "--alpha must be in [0, 1]",
        ),
        (
            vec!["--intrinsics", &cam, "--image", &img, "--alpha", "nan"],
            "--alpha must be in [0, 1]",
        ),
        (
            vec!["--intrinsics", &cam, "--image", &img, "--balance", "0.5"],
            "--balance is for fisheye cameras",
        ),
        // Wrong files: an image as the camera, a camera of another image size.
        (
            vec!["--intrinsics", &img, "--image", &img],
            "camera file extension",
        ),
        (
            vec!["--intrinsics", &cam, "--image", &small],
            "image is 320x240 but",
        ),
    ];
    for (args, expect) in cases {
        let mut all = vec!["undistort"];
        all.extend(args);
        all.extend(["--out", &outs]);
        let o = camgeom(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(expect), "expected `{expect}` in: {err}");
        assert!(!out.exists());
    }
}

#[test]
fn fisheye_camera_files_are_checked() {
    use camgeom_host::intrinsics::{camera_from_json, camera_from_storage};
    let yaml = |model: &str, coeffs: &str| {
        format!(
            "%YAML:1.0\n---\nfisheye_model: {model}\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 300., 0., 320., 0., 300., 240., 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: {}\n   cols: 1\n   dt: d\n   data: [ {coeffs} ]\n",
            coeffs.split(',').count()
        )
    };
    let load = |text: &str| {
        camera_from_storage(&camgeom_host::FileStorage::parse_yaml(text, "f.yml").unwrap())
    };
    // fisheye_model 1 with 4 coefficients: a Kannala-Brandt camera with them, in order.
    let spec = load(&yaml("1", "0.1, -0.02, 0.003, -0.0004")).unwrap();
    match spec.camera.lens {
        Lens::KannalaBrandt(f) => assert_eq!(f.to_opencv(), [0.1, -0.02, 0.003, -0.0004]),
        Lens::BrownConrady(_) => panic!("not a fisheye"),
    }
    // 0 (or absent): Brown-Conrady, 4 coefficients mean k3 = 0.
    let spec = load(&yaml("0", "0.1, -0.02, 0.003, -0.0004")).unwrap();
    assert_eq!(
        spec.camera.lens.coefficients(),
        [0.1, -0.02, 0.003, -0.0004, 0.0]
    );
    // A fisheye needs exactly 4; the flag must be 0 or 1.
    let e = load(&yaml("1", "0.1, 0.2, 0.3, 0.4, 0.5")).unwrap_err();
    assert!(e.to_string().contains("a fisheye camera has 4"), "{e}");
    let e = load(&yaml("2", "0.1, 0.2, 0.3, 0.4")).unwrap_err();
    assert!(
        e.to_string().contains("`fisheye_model` must be 0 or 1"),
        "{e}"
    );
    // camgeom's JSON: `fisheye` and `distortion` exclude each other.
    let e = camera_from_json(
        r#"{"fx": 300, "fy": 300, "cx": 320, "cy": 240, "distortion": [0.1, 0, 0, 0], "fisheye": [0.1, 0, 0, 0]}"#,
        "f.json",
    )
    .unwrap_err();
    assert!(e.to_string().contains("exclude each other"), "{e}");
}

#[test]
fn views_without_the_board_are_listed_and_left_out() {
    let dir = scratch_dir("calibreject");
    let blank = dir.join("blank.png");
    save_gray(&GrayImage::filled(640, 480, 128), &blank).unwrap();
    let odd = dir.join("odd.png");
    save_gray(&GrayImage::filled(641, 481, 128), &odd).unwrap();
    let mut images = bundled_views();
    images.insert(2, blank.display().to_string());
    images.insert(5, odd.display().to_string());
    let pictures = dir.join("pictures");
    let out = dir.join("camera.yml");
    let o = run_calibrate(
        &images,
        &["--pictures", &pictures.display().to_string()],
        &out,
    );
    let j = json(&o);
    assert_eq!(j["views_used"], 13);
    assert_eq!(j["views_rejected"], serde_json::json!(["blank.png"]));
    assert_eq!(j["views_skipped"], serde_json::json!(["odd.png"]));
    let used = j["images_used"].as_array().unwrap();
    assert_eq!(used.len(), 13);
    assert!(!used.contains(&"blank.png".into()));
    assert_eq!(floats(&j["per_view_rms"]).len(), 13);
    // One note on stderr for the view left out, saying what was seen, and one warning for
    // the image of another size.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "blank.png: no 9x6 board found (no chessboard corner among 0 candidates), view not used"
        ),
        "{err}"
    );
    assert!(
        err.contains(
            "odd.png: 641x481, not the 640x480 of most images (another camera mode): skipped"
        ),
        "{err}"
    );
    // The pictures go to --pictures: 14 tiles (4 rows of 4 columns), 13 bars.
    let sheet = load_gray(pictures.join("camera_corners.png")).unwrap();
    assert_eq!(
        (sheet.width, sheet.height),
        (4 * 320 + 5 * 2, 4 * 240 + 5 * 2)
    );
    assert!(pictures.join("camera_reprojection_errors.png").exists());
    assert!(!dir.join("camera_corners.png").exists());
    assert!(out.exists());
}

/// `--corners-out` writes every used view's corners as `view,X,Y,Z,u,v`, and `pose --view K` on
/// that file gives back the pose the calibration reports for view `K` (OpenCV's `rvecs` and
/// `tvecs` are the same refinement of the same correspondences).
#[test]
fn calibrate_writes_poses_and_corners_that_pose_reads() {
    let dir = scratch_dir("corners-out");
    let (camera, corners) = (dir.join("camera.yml"), dir.join("corners.csv"));
    let c = corners.display().to_string();
    let out = run_calibrate(&bundled_views(), &["--corners-out", &c], &camera);
    assert!(out.status.success(), "{out:?}");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let views = v["views"].as_array().unwrap();
    assert_eq!(views.len(), 13);
    let text = std::fs::read_to_string(&corners).unwrap();
    assert!(text.starts_with("view,X,Y,Z,u,v\n"));
    assert_eq!(text.lines().count(), 1 + 13 * 54);
    for w in views.iter().step_by(4) {
        let k = w["view"].as_u64().unwrap().to_string();
        let cam = camera.display().to_string();
        let p = camgeom(&["pose", "--intrinsics", &cam, "--points", &c, "--view", &k]);
        assert!(p.status.success(), "{p:?}");
        let p: Value = serde_json::from_slice(&p.stdout).unwrap();
        for key in ["rvec", "t"] {
            let (a, b) = (&p[key], &w[if key == "t" { "tvec" } else { key }]);
            for i in 0..3 {
                let (x, y) = (a[i].as_f64().unwrap(), b[i].as_f64().unwrap());
                assert!((x - y).abs() < 1e-4 * (1.0 + y.abs()), "{key}: {x} vs {y}");
            }
        }
    }
}
