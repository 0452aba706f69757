//! Frame undistortion against OpenCV (`make_calib_fixtures.py undistort`): the new camera
//! matrix (`getOptimalNewCameraMatrix`, `fisheye::estimateNewCameraMatrixForUndistortRectify`),
//! the lookup table (`initUndistortRectifyMap`, float and `CV_16SC2`), the remapped frame
//! (`remap`, `INTER_LINEAR`), and the compact grid map's added error.

use camgeom::camera::{Camera, Fisheye, Intrinsics};
use camgeom::image::{ImageMut, ImageView};
use camgeom::remap::{GridMap, build_map, grid_len, map_len, new_camera_matrix, remap};

fn fixture(name: &str) -> std::path::PathBuf {
    camgeom_host::data_dir().join("fixtures/calib").join(name)
}

fn json() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(fixture("undistort.json")).unwrap()).unwrap()
}

fn k4(v: &serde_json::Value) -> Intrinsics<f64> {
    let a: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    Intrinsics::new(a[0], a[1], a[2], a[3]).unwrap()
}

fn brown() -> Camera<f64> {
    crate::common::bundled_camera().camera
}

fn fisheye() -> Camera<f64> {
    // SYN_FISHEYE of the fixture script.
    Camera::fisheye(
        Intrinsics::new(260.0, 258.0, 322.0, 238.0).unwrap(),
        Fisheye::from_opencv([0.06, -0.02, 0.008, -0.002]).unwrap(),
    )
}

/// `pattern()` of the fixture script.
fn pattern(w: usize, h: usize) -> Vec<u8> {
    let mut v = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            v[y * w + x] = ((((x / 8 + y / 8) % 2) * 150 + (x + 2 * y) % 100) % 256) as u8;
        }
    }
    v
}

struct Sample {
    model: String,
    x: usize,
    y: usize,
    m: [f64; 2],
    q: [i32; 2],
}

fn samples() -> Vec<Sample> {
    let text = std::fs::read_to_string(fixture("undistort_map.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Sample {
                model: f[0].into(),
                x: f[1].parse().unwrap(),
                y: f[2].parse().unwrap(),
                m: [f[3].parse().unwrap(), f[4].parse().unwrap()],
                q: [f[5].parse().unwrap(), f[6].parse().unwrap()],
            }
        })
        .collect()
}

#[test]
fn new_camera_matrix_matches_opencv() {
    let j = json();
    for (name, cam) in [("brown", brown()), ("fisheye", fisheye())] {
        for a in ["0.0", "0.5", "1.0"] {
            let ours = new_camera_matrix(&cam, 640, 480, a.parse().unwrap()).unwrap();
            let cv = k4(&j[name][a]);
            let d = [
                ours.fx() - cv.fx(),
                ours.fy() - cv.fy(),
                ours.cx() - cv.cx(),
                ours.cy() - cv.cy(),
            ];
            println!(
                "{name} {a}: ours {:.4} {:.4} {:.4} {:.4} diff {d:?}",
                ours.fx(),
                ours.fy(),
                ours.cx(),
                ours.cy()
            );
            // Both sample the same outline; OpenCV undistorts it with 5 fixed-point iterations
            // (undistortPoints' default criteria) where camgeom's Newton runs to rounding:
            // that leaves up to ~0.1 px in the matrix for this strong barrel lens.
            assert!(d.iter().all(|x| x.abs() < 0.2), "{name} {a}: {d:?}");
        }
    }
}

#[test]
fn map_matches_opencv_and_remap_is_opencvs() {
    let j = json();
    let (w, h) = (640, 480);
    for (name, cam, knew) in [
        ("brown", brown(), k4(&j["brown"]["0.0"])),
        ("fisheye", fisheye(), k4(&j["fisheye"]["0.5"])),
    ] {
        let mut map = vec![[0i16; 2]; map_len(w, h)];
        build_map(&cam, &knew, w, h, &mut map).unwrap();
        let (mut worst_f, mut lsb_diff, mut n) = (0.0f64, 0usize, 0usize);
        for s in samples().iter().filter(|s| s.model == name) {
            let e = map[s.y * w + s.x];
            if s.m[0] < 0.0 || s.m[1] < 0.0 || s.m[0] > 639.0 || s.m[1] > 479.0 {
                continue;
            }
            let ours = [e[0] as f64 / 32.0, e[1] as f64 / 32.0];
            worst_f = worst_f
                .max((ours[0] - s.m[0]).abs())
                .max((ours[1] - s.m[1]).abs());
            let dq = (e[0] as i32 - s.q[0])
                .abs()
                .max((e[1] as i32 - s.q[1]).abs());
            assert!(dq <= 1, "{name} at {},{}: {e:?} vs {:?}", s.x, s.y, s.q);
            lsb_diff += (dq != 0) as usize;
            n += 1;
        }
        println!(
            "{name}: {n} samples, max |map - OpenCV float| {worst_f:.4} px, {lsb_diff} entries 1/32 px off OpenCV's CV_16SC2"
        );
        // Rounding to 1/32 px bounds the difference by 1/64 px, plus float32 map rounding.
        assert!(worst_f <= 1.0 / 64.0 + 1e-4);
        if name == "brown" {
            let src = pattern(w, h);
            let mut out = vec![0u8; w * h];
            remap(
                &ImageView::packed(&src, w, h).unwrap(),
                &map,
                &mut ImageMut::packed(&mut out, w, h).unwrap(),
                0,
            )
            .unwrap();
            let cv = camgeom_host::images::load_gray(fixture("undistort_remap.png")).unwrap();
            let diffs: Vec<i32> = out
                .iter()
                .zip(&cv.data)
                .map(|(a, b)| (*a as i32 - *b as i32).abs())
                .collect();
            let equal = diffs.iter().filter(|d| **d == 0).count();
            let max = diffs.iter().max().unwrap();
            println!(
                "remap: {equal} of {} pixels equal to OpenCV's, max diff {max}",
                w * h
            );
            // The same integer arithmetic: pixels differ only where a map entry is 1/32 px off
            // (a tie in the rounding), by at most the image's change over 1/32 px.
            assert!(equal as f64 >= 0.99 * (w * h) as f64);
            assert!(*max <= 8);
        }
    }
}

#[test]
fn grid_map_error() {
    let j = json();
    let (w, h) = (640, 480);
    for (name, cam, knew) in [
        ("brown", brown(), k4(&j["brown"]["0.0"])),
        ("fisheye", fisheye(), k4(&j["fisheye"]["0.5"])),
    ] {
        let mut map = vec![[0i16; 2]; map_len(w, h)];
        build_map(&cam, &knew, w, h, &mut map).unwrap();
        for shift in [3u32, 4, 5] {
            let mut nodes = vec![[0i32; 2]; grid_len(w, h, shift)];
            let g = GridMap::build(&cam, &knew, w, h, shift, &mut nodes).unwrap();
            let (mut worst, mut sum) = (0i32, 0i64);
            for y in 0..h {
                for x in 0..w {
                    let a = g.entry(x, y);
                    let b = map[y * w + x];
                    let d = (a[0] - b[0] as i32).abs().max((a[1] - b[1] as i32).abs());
                    worst = worst.max(d);
                    sum += d as i64;
                }
            }
            println!(
                "{name} grid {} px ({} nodes, {} bytes): max {:.4} px, mean {:.5} px from the full map",
                1 << shift,
                grid_len(w, h, shift),
                grid_len(w, h, shift) * 8,
                worst as f64 / 32.0,
                sum as f64 / (w * h) as f64 / 32.0
            );
            if shift == 3 {
                // 8-px nodes: bilinear interpolation errs by the map's curvature times
                // (8 px)² / 8; for these lenses (strong barrel, wide fisheye) that stays within
                // 1/8 px at the frame's corners (measured 0.06 and 0.09 px).
                assert!(worst <= 4, "{name}: {worst}");
            }
        }
    }
}
