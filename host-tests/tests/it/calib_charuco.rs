//! ChArUco calibration (#41): the board layout against OpenCV's (`charuco_layout.py`), and
//! `camgeom calibrate --board charuco:...` on the rendered sets of `charuco_render.py`, where
//! no view shows the whole board, against the exact truth (bounds from
//! `bench_charuco.py`, BENCHMARKS.md "ChArUco calibration"); a refusal with too few corners.

use std::path::PathBuf;

use camgeom::apriltag::families;
use camgeom::charuco::CharucoBoard;

use crate::common::{camgeom, json};

const SPEC: &str = "charuco:11x8:0.030:0.022:DICT_4X4_50";

fn dir(set: &str) -> PathBuf {
    camgeom_host::data_dir().join("charuco").join(set)
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

/// Marker ids, marker corners and chessboard corners of four boards (odd and even sides) as
/// OpenCV's `CharucoBoard` lays them out.
#[test]
fn charuco_layout_matches_opencv() {
    let text =
        std::fs::read_to_string(camgeom_host::data_dir().join("charuco/layout.csv")).unwrap();
    let mut rows = 0;
    for l in text.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        let (x, y) = f[0].split_once('x').unwrap();
        let b = CharucoBoard::new(
            x.parse().unwrap(),
            y.parse().unwrap(),
            0.04,
            0.03,
            &families::DICT_4X4_50,
        )
        .unwrap();
        let (id, k): (usize, usize) = (f[2].parse().unwrap(), f[3].parse().unwrap());
        let (px, py): (f32, f32) = (f[4].parse().unwrap(), f[5].parse().unwrap());
        let p = match f[1] {
            "marker" => b.marker_corners(id).unwrap()[k],
            _ => b.corner(id).unwrap(),
        };
        assert!(
            (p.x - px).abs() < 1e-6 && (p.y - py).abs() < 1e-6,
            "{l}: {p:?}"
        );
        rows += 1;
    }
    assert_eq!(rows, 452);
    // Each corner's two markers touch it.
    let b = CharucoBoard::new(6, 5, 0.04, 0.03, &families::DICT_4X4_50).unwrap();
    for c in 0..b.corners() {
        let p = b.corner(c).unwrap();
        for m in b.corner_markers(c).unwrap() {
            let q = b.marker_corners(m).unwrap();
            let d = q.iter().map(|q| (q - p).norm()).fold(f32::MAX, f32::min);
            assert!(
                (d - 0.005 * 2f32.sqrt()).abs() < 1e-6,
                "corner {c} marker {m}"
            );
        }
    }
}

/// The truth's corners of each view: no view shows the whole board (70 corners).
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
fn calibrate_set(
    set: &str,
    fisheye: bool,
    truth_k: [f64; 4],
    bound_px: f64,
    rms: f64,
    views: usize,
) {
    let imgs = images(set);
    let t = truth_rows(set);
    for v in 0..imgs.len() {
        let n = t.iter().filter(|r| r.0 == v).count();
        assert!(n < 70, "view {v} shows the whole board");
    }
    let out = scratch(&format!("charuco_{set}"));
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
    assert!(j["rms_px"].as_f64().unwrap() < rms, "{j}");
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
    // Every corner within 1 px of the truth, the median within 0.03 px.
    let text = std::fs::read_to_string(&corners).unwrap();
    let mut errs = vec![];
    for l in text.lines().skip(1) {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        let view: usize = imgs[f[0] as usize][imgs[f[0] as usize].len() - 6..][..2]
            .parse()
            .unwrap();
        let id = ((f[2] / 0.030 - 1.0).round() * 10.0 + (f[1] / 0.030 - 1.0).round()) as usize;
        let r = t
            .iter()
            .find(|r| r.0 == view && r.1 == id)
            .expect("a corner in the image");
        errs.push((f[4] - r.2).hypot(f[5] - r.3));
    }
    errs.sort_by(f64::total_cmp);
    assert!(errs.len() > 300, "{}", errs.len());
    assert!(
        errs[errs.len() / 2] < 0.03,
        "median {}",
        errs[errs.len() / 2]
    );
    assert!(*errs.last().unwrap() < 1.0, "max {}", errs.last().unwrap());
}

#[test]
fn charuco_brown_no_view_shows_the_whole_board() {
    calibrate_set("brown", false, [520.0, 516.0, 322.5, 238.0], 0.3, 0.1, 10);
}

#[test]
fn charuco_fisheye_no_view_shows_the_whole_board() {
    // Every view used: the corners near the frame's edge, where the lens bends the markers,
    // are predicted from the markers' nearest corners, and a wide view's start pose comes from
    // its points nearest the axis.
    calibrate_set("fisheye", true, [300.0, 299.0, 318.0, 242.5], 0.3, 0.1, 10);
}

/// Images without the board: a one-line refusal, exit 2, no file.
#[test]
fn charuco_refuses_too_few_corners() {
    let aruco = camgeom_host::data_dir().join("aruco");
    let imgs: Vec<String> = (0..3)
        .map(|i| aruco.join(format!("000{i}.png")).display().to_string())
        .collect();
    let out = scratch("charuco_refusal").join("cam.yml");
    let o = out.display().to_string();
    let mut args = vec!["calibrate", "--images"];
    args.extend(imgs.iter().map(String::as_str));
    args.extend(["--board", SPEC, "--out", &o]);
    let r = camgeom(&args);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("calibration needs at least 3 views"), "{err}");
    assert!(!out.exists());
    // A bad spec is a usage error too.
    let r = camgeom(&[
        "calibrate",
        "--images",
        &imgs[0],
        "--board",
        "charuco:11x8:30:40:DICT_4X4_50",
        "--out",
        &o,
    ]);
    assert_eq!(r.status.code(), Some(2));
}

/// The library's corners of one rendered view: markers by the board's dictionary, then
/// `interpolate_corners` with the defaults; `(id, x, y)`.
fn library_corners(
    board: &CharucoBoard,
    img: &camgeom_host::images::GrayImage,
) -> Vec<(usize, f32, f32)> {
    use camgeom::apriltag::{Detector, DetectorConfig};
    use camgeom::charuco::{CharucoCorner, CharucoParams, interpolate_corners};
    let det = Detector::new(DetectorConfig::default(), &[&families::DICT_4X4_50]).unwrap();
    let mut ws: Box<camgeom_host::apriltag::HostWorkspace> = Box::default();
    let view = img.view().unwrap();
    let markers = ws.detect::<256>(&det, &view).unwrap();
    let mut out = vec![CharucoCorner::default(); board.corners()];
    let n =
        interpolate_corners(board, &view, &markers, &CharucoParams::default(), &mut out).unwrap();
    out[..n]
        .iter()
        .map(|c| (usize::from(c.id), c.point.x, c.point.y))
        .collect()
}

/// Refusals. The most oblique Brown-Conrady view (04), where the markers' corners come within
/// the saddle window's reach of some chessboard corners: every corner kept is within 0.2 px of
/// the truth (the refinement that does not converge is refused; it once kept one 0.82 px off).
/// Grey patches over three kept corners, each off its centre: at least one of them refused,
/// any kept still nearest its own truth (within 2 px: a converged saddle on the patch's edge
/// is not refused, a limit of the convergence test), the others within 0.2 px as before. Boards of other
/// layouts with the same dictionary (the same marker ids elsewhere): no corner in any view.
#[test]
fn charuco_corners_refusals() {
    let board = CharucoBoard::new(11, 8, 0.030, 0.022, &families::DICT_4X4_50).unwrap();
    let t = truth_rows("brown");
    let truth = |view: usize, id: usize| {
        t.iter()
            .find(|r| r.0 == view && r.1 == id)
            .map(|r| (r.2 as f32, r.3 as f32))
    };
    let mut img = camgeom_host::images::load_gray(dir("brown").join("04.png")).unwrap();
    let kept = library_corners(&board, &img);
    assert!(kept.len() >= 60, "{}", kept.len());
    for &(id, x, y) in &kept {
        let (tx, ty) = truth(4, id).expect("a corner in the image");
        assert!(
            (x - tx).hypot(y - ty) < 0.2,
            "corner {id}: {x} {y} against {tx} {ty}"
        );
    }
    // Cover three corners with grey squares of 9x9 px centred 3 px off them.
    let covered: Vec<(usize, f32, f32)> = kept.iter().step_by(20).copied().take(3).collect();
    for &(_, x, y) in &covered {
        let (cx, cy) = (x.round() as i64 + 3, y.round() as i64 + 2);
        for yy in cy - 4..=cy + 4 {
            for xx in cx - 4..=cx + 4 {
                img.data[yy as usize * img.width + xx as usize] = 128;
            }
        }
    }
    let after = library_corners(&board, &img);
    for &(id, x, y) in &after {
        let (tx, ty) = truth(4, id).unwrap();
        let e = (x - tx).hypot(y - ty);
        if covered.iter().any(|c| c.0 == id) {
            // A covered corner may still converge on the patch's own edges: never at another
            // corner's place (the id stays right), but not as accurate (measured 1.2 px).
            let nearest = t
                .iter()
                .filter(|r| r.0 == 4)
                .min_by(|a, b| {
                    let da = (a.2 as f32 - x).hypot(a.3 as f32 - y);
                    let db = (b.2 as f32 - x).hypot(b.3 as f32 - y);
                    da.total_cmp(&db)
                })
                .unwrap();
            assert_eq!(nearest.1, id, "covered corner {id} at {x} {y}");
            assert!(e < 2.0, "covered corner {id}: {e} px");
        } else {
            assert!(
                e < 0.2,
                "covered view, corner {id}: {x} {y} against {tx} {ty}"
            );
        }
    }
    let refused = covered
        .iter()
        .filter(|c| !after.iter().any(|a| a.0 == c.0))
        .count();
    assert!(refused >= 1, "{refused} of the covered corners refused");
    assert!(after.len() + 3 >= kept.len());
    // Other layouts, the same dictionary.
    for (cols, rows) in [(8, 6), (9, 8), (7, 7), (5, 5)] {
        let wrong = CharucoBoard::new(cols, rows, 0.030, 0.022, &families::DICT_4X4_50).unwrap();
        for f in images("brown") {
            let img = camgeom_host::images::load_gray(&f).unwrap();
            let c = library_corners(&wrong, &img);
            assert!(c.is_empty(), "{cols}x{rows} board on {f}: {c:?}");
        }
    }
}
