//! Camera calibration on the host: one 640x480 chessboard detection of the bundled `left01.jpg`
//! (9x6) with the default saddle-point refinement and with `cornerSubPix` 5x5 (OpenCV's
//! `findChessboardCorners` + `cornerSubPix`), and the 13-view calibration (Zhang + joint
//! Levenberg-Marquardt, flags 0) in f64 and f32, Brown-Conrady and fisheye, from OpenCV's own
//! 5x5-refined corners (`host-tests/data/fixtures/calib/real_corners.csv`), the input
//! `host-tests/scripts/bench_calib.py` runs OpenCV's `calibrateCamera` and `fisheye.calibrate`
//! on.
//!
//! ```sh
//! cargo bench -p camgeom-host --bench calib
//! python3 host-tests/scripts/bench_calib.py --criterion target/criterion
//! ```

use std::hint::black_box;

use camgeom::Real;
use camgeom::calib::{CalibrationConfig, Calibrator};
use camgeom::camera::LensModel;
use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SubPixConfig, scratch_len,
};
use camgeom::nalgebra::Point2;
use camgeom_host::images::load_gray;
use criterion::{Criterion, criterion_group, criterion_main};

/// OpenCV's 5x5-refined corners of the 13 views, in its order (column `u5,v5`).
fn opencv_corners() -> Vec<Vec<Point2<f64>>> {
    let path = camgeom_host::data_dir().join("fixtures/calib/real_corners.csv");
    let text = std::fs::read_to_string(path).expect("real_corners.csv");
    let mut views: Vec<(String, Vec<Point2<f64>>)> = Vec::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let p = Point2::new(f[4].parse().expect("u5"), f[5].parse().expect("v5"));
        match views.last_mut() {
            Some((name, v)) if name == f[0] => v.push(p),
            _ => views.push((f[0].to_string(), vec![p])),
        }
    }
    views.into_iter().map(|(_, v)| v).collect()
}

fn calibrator<T: Real>(views: &[Vec<Point2<f64>>]) -> Box<Calibrator<T, 16, 54>> {
    let board = BoardSize::new(9, 6).expect("board");
    let mut cal = Box::new(Calibrator::<T, 16, 54>::new(board, T::one(), 640, 480).expect("cal"));
    for v in views {
        let px: Vec<Point2<T>> = v
            .iter()
            .map(|p| Point2::new(T::lit(p.x), T::lit(p.y)))
            .collect();
        cal.add_view(640, 480, &px).expect("view");
    }
    cal
}

fn bench_calibration<T: Real>(c: &mut Criterion, ty: &str, views: &[Vec<Point2<f64>>]) {
    for (name, model) in [
        ("brown", LensModel::BrownConrady),
        ("fisheye", LensModel::KannalaBrandt),
    ] {
        let mut cal = calibrator::<T>(views);
        let cfg = CalibrationConfig {
            model,
            ..CalibrationConfig::default()
        }
        .check()
        .expect("config");
        let r = cal.solve(&cfg).expect("solve");
        println!(
            "calibrate13 {name} {ty}: rms {:.6} px, {} iterations",
            r.rms_px.to_f64(),
            r.iterations
        );
        c.bench_function(&format!("calib/calibrate13_{name}/{ty}"), |b| {
            b.iter(|| black_box(cal.solve(black_box(&cfg))).is_ok())
        });
    }
}

fn calib(c: &mut Criterion) {
    let img = load_gray(camgeom_host::data_dir().join("chessboard/left01.jpg")).expect("left01");
    let view = img.view().expect("view");
    let board = BoardSize::new(9, 6).expect("board");
    let mut det = Box::new(ChessboardDetector::<512>::new());
    let mut scratch = vec![0i32; scratch_len(img.width)];
    // OpenCV's winSize (5, 5), an 11x11 window, 30 iterations / 0.1 (its acceptance test).
    let sp5 = SubPixConfig {
        half_window: 5,
        max_iterations: 30,
        epsilon: 0.1,
    };
    for (name, refine) in [
        ("saddle", DetectConfig::default().refine),
        ("cornersubpix5", Refinement::CornerSubPix(sp5)),
    ] {
        let params = DetectConfig {
            refine,
            ..DetectConfig::default()
        }
        .check()
        .expect("config");
        let found = det
            .detect::<54>(&view, board, &params, &mut scratch)
            .expect("detect");
        assert!(found.is_some(), "left01: board not found");
        c.bench_function(&format!("calib/detect_left01/{name}"), |b| {
            b.iter(|| {
                black_box(det.detect::<54>(black_box(&view), board, &params, &mut scratch))
                    .is_ok_and(|f| f.is_some())
            })
        });
    }
    let views = opencv_corners();
    assert_eq!(views.len(), 13);
    bench_calibration::<f64>(c, "f64", &views);
    bench_calibration::<f32>(c, "f32", &views);
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(3));
    targets = calib
}
criterion_main!(benches);
