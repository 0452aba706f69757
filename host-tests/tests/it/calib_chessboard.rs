//! Chessboard detection on the 13 bundled views, side by side with OpenCV's
//! `findChessboardCorners` + `cornerSubPix` (`host-tests/scripts/make_calib_fixtures.py`,
//! `fixtures/calib/real_corners.csv`).

use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SubPixConfig, scratch_len,
};
use camgeom::nalgebra::Point2;

/// One view of the fixture: OpenCV's corners in its own order.
pub struct OpenCvView {
    pub name: String,
    pub raw: Vec<Point2<f64>>,
    pub subpix5: Vec<Point2<f64>>,
    pub subpix11: Vec<Point2<f64>>,
}

pub fn opencv_views() -> Vec<OpenCvView> {
    let path = camgeom_host::data_dir().join("fixtures/calib/real_corners.csv");
    let text = std::fs::read_to_string(path).unwrap();
    let mut out: Vec<OpenCvView> = Vec::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let v: Vec<f64> = f[2..8].iter().map(|s| s.parse().unwrap()).collect();
        if out.last().is_none_or(|o| o.name != f[0]) {
            out.push(OpenCvView {
                name: f[0].to_string(),
                raw: vec![],
                subpix5: vec![],
                subpix11: vec![],
            });
        }
        let o = out.last_mut().unwrap();
        o.raw.push(Point2::new(v[0], v[1]));
        o.subpix5.push(Point2::new(v[2], v[3]));
        o.subpix11.push(Point2::new(v[4], v[5]));
    }
    out
}

/// camgeom's corners of one bundled view with the given refinement.
pub fn detect(name: &str, refine: Refinement) -> Option<Vec<Point2<f64>>> {
    let img =
        camgeom_host::images::load_gray(crate::common::chessboard(&format!("{name}.jpg"))).unwrap();
    let mut det = Box::new(ChessboardDetector::<512>::new());
    let mut scratch = vec![0i32; scratch_len(img.width)];
    let params = DetectConfig {
        refine,
        ..DetectConfig::default()
    }
    .check()
    .unwrap();
    let board = BoardSize::new(9, 6).unwrap();
    det.detect::<54>(&img.view().unwrap(), board, &params, &mut scratch)
        .unwrap()
        .map(|b| b.corners.iter().map(|p| p.cast::<f64>()).collect())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

#[test]
fn finds_every_bundled_view_in_opencv_order() {
    let sp5 = SubPixConfig {
        half_window: 5,
        max_iterations: 30,
        epsilon: 0.1,
    };
    let mut all_raw = vec![];
    let mut all_sp = vec![];
    for v in opencv_views() {
        let raw =
            detect(&v.name, Refinement::None).unwrap_or_else(|| panic!("{} not found", v.name));
        let d: Vec<f64> = raw
            .iter()
            .zip(&v.raw)
            .map(|(a, b)| (a - b).norm())
            .collect();
        let sp = detect(&v.name, Refinement::CornerSubPix(sp5)).unwrap();
        let e: Vec<f64> = sp
            .iter()
            .zip(&v.subpix5)
            .map(|(a, b)| (a - b).norm())
            .collect();
        println!(
            "{}: raw median {:.3} max {:.3}; subpix5 median {:.4} max {:.4}",
            v.name,
            median(d.clone()),
            d.iter().cloned().fold(0.0, f64::max),
            median(e.clone()),
            e.iter().cloned().fold(0.0, f64::max)
        );
        all_raw.extend(d);
        all_sp.extend(e);
    }
    let max_raw = all_raw.iter().cloned().fold(0.0, f64::max);
    let max_sp = all_sp.iter().cloned().fold(0.0, f64::max);
    println!(
        "all: raw median {:.3} max {max_raw:.3}; subpix5 median {:.4} max {max_sp:.4}",
        median(all_raw.clone()),
        median(all_sp.clone())
    );
    // Same order: a corner matched to the wrong OpenCV corner is a square (≥ 20 px) away.
    assert!(max_raw < 2.0);
}
