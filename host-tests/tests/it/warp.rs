//! camgeom's perspective warp against `cv2.warpPerspective`, and its clipping at the frame
//! border (fixture from `host-tests/scripts/make_feature_fixtures.py`).

use camgeom::arith::Fixed;
use camgeom::homography::Homography;
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::warp::{WarpConfig, warp_into_quad};
use camgeom_host::images::{GrayImage, load_gray};

/// The script's `checker_logo()`: 128x128, 16-px cells of 230 and 30 (the features bench's).
fn checker() -> GrayImage {
    camgeom_host::bench::warp_case().0
}

fn figures() -> serde_json::Value {
    let path = camgeom_host::data_dir().join("features/opencv_orb_figures.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn quad_from(v: &serde_json::Value) -> [Point2<f32>; 4] {
    let q = v.as_array().unwrap();
    core::array::from_fn(|i| {
        Point2::new(
            q[i][0].as_f64().unwrap() as f32,
            q[i][1].as_f64().unwrap() as f32,
        )
    })
}

fn warp(quad: &[Point2<f32>; 4], frame: (usize, usize), arithmetic: &str) -> (GrayImage, u32) {
    let logo = checker();
    let mut out = GrayImage::filled(frame.0, frame.1, 100);
    let cfg = WarpConfig { alpha: 255 };
    let (src, mut dst) = (logo.view().unwrap(), out.view_mut().unwrap());
    let r = match arithmetic {
        "fixed" => warp_into_quad::<Fixed>(&src, &mut dst, quad, &cfg),
        _ => warp_into_quad::<f32>(&src, &mut dst, quad, &cfg),
    }
    .unwrap();
    (out, r.written)
}

/// The same quadrilateral as the fixture: camgeom (float and fixed point) against
/// `cv2.warpPerspective(INTER_LINEAR, BORDER_TRANSPARENT)` on the pixels whose source point is
/// at least one pixel inside the logo (on the outline OpenCV and camgeom legitimately differ:
/// OpenCV also blends in the transparent border there).
///
/// Measure: mean absolute difference below 0.1 grey levels and no pixel off by more than 2
/// (measured: float 0.000 mean, max 1; fixed 0.021, max 1). OpenCV quantises source
/// coordinates to 1/32 px (`INTER_BITS = 5`) and camgeom's fixed path to 1/256 px, so on the
/// checker's 200-level edges a difference of a grey level or two is rounding, not error.
#[test]
fn checker_warp_matches_opencv_inside_the_quad() {
    let fig = figures();
    let quad = quad_from(&fig["warp_checker"]["quad"]);
    let cv = load_gray(camgeom_host::data_dir().join("features/warp_checker_opencv.png")).unwrap();
    let h: Vec<f64> = fig["warp_checker"]["H"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
        .collect();
    let hinv = Homography::from_matrix(&Matrix3::from_row_slice(&h))
        .unwrap()
        .inverse()
        .unwrap();
    for arithmetic in ["f32", "fixed"] {
        let (ours, written) = warp(&quad, (320, 240), arithmetic);
        let (mut n, mut sum, mut big, mut worst) = (0usize, 0u64, 0usize, 0u8);
        for y in 0..240 {
            for x in 0..320 {
                let s = hinv.transfer(&Point2::new(x as f64, y as f64)).unwrap();
                if s.x >= 1.0 && s.y >= 1.0 && s.x <= 126.0 && s.y <= 126.0 {
                    let d = ours.at(x, y).abs_diff(cv.at(x, y));
                    n += 1;
                    sum += u64::from(d);
                    big += usize::from(d > 4);
                    worst = worst.max(d);
                }
            }
        }
        let mean = sum as f64 / n as f64;
        println!(
            "warp {arithmetic}: {written} pixels written, {n} compared, mean |camgeom - OpenCV| = {mean:.3}, \
             {big} pixels > 4, max {worst}"
        );
        assert!(n > 20_000, "{n}");
        assert!(mean < 0.1, "{mean}");
        assert!(worst <= 2 && big == 0, "{worst}");
        // Everything outside the quadrilateral is untouched.
        let changed_outside = (0..240 * 320)
            .filter(|&i| {
                let s = hinv
                    .transfer(&Point2::new((i % 320) as f64, (i / 320) as f64))
                    .unwrap();
                let outside = s.x < -0.01 || s.y < -0.01 || s.x > 127.01 || s.y > 127.01;
                outside && ours.data[i] != 100
            })
            .count();
        assert_eq!(changed_outside, 0);
    }
}

/// A quadrilateral partly outside the frame (every side in turn) against the same warp into a
/// frame large enough to hold it, cropped: the clipped warp writes exactly the pixels of the
/// crop, with the same values up to 1 grey level (the two frames' coordinates round
/// differently).
#[test]
fn clipping_matches_the_cropped_unclipped_warp() {
    let base = [
        (-40.0f32, -30.0f32),
        (150.0, -10.0),
        (170.0, 130.0),
        (-60.0, 110.0),
    ];
    let (pad_x, pad_y) = (200usize, 150usize);
    for (dx, dy) in [
        (0.0, 0.0),
        (250.0, 0.0),
        (100.0, 160.0),
        (260.0, 170.0),
        (-300.0, 0.0),
    ] {
        for arithmetic in ["f32", "fixed"] {
            let quad = base.map(|(x, y)| Point2::new(x + dx, y + dy));
            let big_quad =
                base.map(|(x, y)| Point2::new(x + dx + pad_x as f32, y + dy + pad_y as f32));
            let (small, written) = warp(&quad, (320, 240), arithmetic);
            let (big, _) = warp(&big_quad, (320 + 2 * pad_x, 240 + 2 * pad_y), arithmetic);
            let mut crop_written = 0u32;
            let mut worst = 0u8;
            let mut set_diff = 0;
            for y in 0..240 {
                for x in 0..320 {
                    let (a, b) = (small.at(x, y), big.at(x + pad_x, y + pad_y));
                    crop_written += u32::from(b != 100);
                    if (a != 100) != (b != 100) {
                        set_diff += 1;
                    } else {
                        worst = worst.max(a.abs_diff(b));
                    }
                }
            }
            println!(
                "clip {dx},{dy} {arithmetic}: written {written}, crop {crop_written}, set diff {set_diff}, max diff {worst}"
            );
            assert!(worst <= 1, "{worst}");
            // Only outline pixels can flip (the logo has no pixel of value 100).
            assert!(set_diff <= 40, "{set_diff}");
            if dx < -200.0 {
                assert_eq!(written, 0);
            }
        }
    }
}

/// `camgeom warp` end to end: the fixture's quadrilateral, then a folded one (status 2).
#[test]
fn cli_warp() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("camgeom-warp-cli");
    std::fs::create_dir_all(&dir).unwrap();
    let logo = dir.join("logo.png");
    camgeom_host::images::save_gray(&checker(), &logo).unwrap();
    let frame = dir.join("frame.png");
    camgeom_host::images::save_gray(&GrayImage::filled(320, 240, 100), &frame).unwrap();
    let quad = quad_from(&figures()["warp_checker"]["quad"]);
    let corners = dir.join("corners.csv");
    let rows: String = quad.iter().map(|p| format!("{},{}\n", p.x, p.y)).collect();
    std::fs::write(&corners, format!("x,y\n{rows}")).unwrap();
    let out = dir.join("out.png");
    let run = |corners: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_camgeom"))
            .arg("warp")
            .arg("--logo")
            .arg(&logo)
            .arg("--frame")
            .arg(&frame)
            .arg("--corners")
            .arg(corners)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let ok = run(&corners);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&ok.stdout).unwrap();
    assert_eq!(json["arithmetic"], "float");
    let (expected, written) = warp(&quad, (320, 240), "f32");
    assert_eq!(json["written"].as_u64().unwrap(), u64::from(written));
    assert_eq!(load_gray(&out).unwrap(), expected);
    let bowtie = dir.join("bowtie.csv");
    std::fs::write(&bowtie, "0,0\n100,100\n100,0\n0,100\n").unwrap();
    let bad = run(&bowtie);
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("degenerate") && err.lines().count() == 1,
        "{err}"
    );
}
