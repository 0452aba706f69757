//! Calibration of the 13 bundled views against OpenCV: OpenCV's own acceptance test
//! (`modules/python/test/test_calibration.py`) on OpenCV's corners, and camgeom's detector +
//! calibration against OpenCV's detector + calibration (`fixtures/calib/real_opencv.json`).

use camgeom::Real;
use camgeom::calib::{CalibrationConfig, CalibrationReport, Calibrator};
use camgeom::chessboard::{BoardSize, Refinement, SaddleConfig, SubPixConfig};
use camgeom::nalgebra::Point2;

use super::calib_chessboard::{detect, opencv_views};

fn opencv_json() -> serde_json::Value {
    let path = camgeom_host::data_dir().join("fixtures/calib/real_opencv.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

pub fn calibrate<T: Real>(
    views: &[Vec<Point2<f64>>],
    cfg: &CalibrationConfig,
) -> CalibrationReport<T, 32> {
    let board = BoardSize::new(9, 6).unwrap();
    let mut cal = Box::new(Calibrator::<T, 32, 100>::new(board, T::lit(1.0), 640, 480).unwrap());
    for v in views {
        let px: Vec<Point2<T>> = v
            .iter()
            .map(|p| Point2::new(T::lit(p.x), T::lit(p.y)))
            .collect();
        cal.add_view(640, 480, &px).unwrap();
    }
    cal.solve(&cfg.check().unwrap()).unwrap()
}

fn summary<T: Real>(r: &CalibrationReport<T, 32>) -> String {
    let k = &r.camera.intrinsics;
    let d = r.camera.lens.coefficients();
    format!(
        "rms {:.6} fx {:.4} fy {:.4} cx {:.4} cy {:.4} dist [{:.5} {:.5} {:.6} {:.6} {:.5}] it {} std {:?}",
        r.rms_px.to_f64(),
        k.fx().to_f64(),
        k.fy().to_f64(),
        k.cx().to_f64(),
        k.cy().to_f64(),
        d[0].to_f64(),
        d[1].to_f64(),
        d[2].to_f64(),
        d[3].to_f64(),
        d[4].to_f64(),
        r.iterations,
        r.std.map(|x| (x.to_f64() * 1e4).round() / 1e4)
    )
}

/// OpenCV's test: RMS within 0.01 of 0.196334638034, `|K - K_test|₁ < 10`,
/// `|d - d_test|₁ < 0.05`.
fn opencv_acceptance<T: Real>(r: &CalibrationReport<T, 32>) {
    let k = &r.camera.intrinsics;
    let k_test = [532.80992189, 532.93346422, 342.4952186, 233.8879292];
    let d_test = [
        -2.81325576e-01,
        2.91130406e-02,
        1.21234330e-03,
        -1.40825372e-04,
        1.54865844e-01,
    ];
    assert!(
        (r.rms_px.to_f64() - 0.196334638034).abs() < 0.01,
        "{}",
        summary(r)
    );
    let kl1 = (k.fx().to_f64() - k_test[0]).abs()
        + (k.fy().to_f64() - k_test[1]).abs()
        + (k.cx().to_f64() - k_test[2]).abs()
        + (k.cy().to_f64() - k_test[3]).abs()
        + k.skew().to_f64().abs();
    assert!(kl1 < 10.0, "K L1 {kl1}: {}", summary(r));
    let d = r.camera.lens.coefficients();
    let dl1: f64 = d
        .iter()
        .zip(d_test)
        .map(|(a, b)| (a.to_f64() - b).abs())
        .sum();
    assert!(dl1 < 0.05, "dist L1 {dl1}: {}", summary(r));
}

#[test]
fn passes_opencvs_acceptance_test_on_opencvs_corners() {
    let views: Vec<Vec<Point2<f64>>> = opencv_views().into_iter().map(|v| v.subpix5).collect();
    let cfg = CalibrationConfig::default();
    let r64 = calibrate::<f64>(&views, &cfg);
    println!("f64: {}", summary(&r64));
    let r32 = calibrate::<f32>(&views, &cfg);
    println!("f32: {}", summary(&r32));
    let cv = &opencv_json()["subpix5"];
    println!(
        "opencv: rms {} K {} dist {} std {}",
        cv["rms"], cv["K"], cv["dist"], cv["std_intrinsics"]
    );
    opencv_acceptance(&r64);
    opencv_acceptance(&r32);
}

#[test]
fn own_corners_reach_opencvs_rms() {
    let sp5 = SubPixConfig {
        half_window: 5,
        max_iterations: 30,
        epsilon: 0.1,
    };
    let names: Vec<String> = opencv_views().into_iter().map(|v| v.name).collect();
    let views: Vec<Vec<Point2<f64>>> = names
        .iter()
        .map(|n| detect(n, Refinement::CornerSubPix(sp5)).unwrap())
        .collect();
    let r = calibrate::<f64>(&views, &CalibrationConfig::default());
    println!("own corners f64: {}", summary(&r));
    let cv = opencv_json()["subpix5"]["rms"].as_f64().unwrap();
    assert!(r.rms_px <= cv, "{} vs OpenCV {cv}", r.rms_px);
    // OpenCV's calibration sample refines with winSize (11, 11), a 23x23 window: on left02 it
    // reaches over the thin last row of squares and pulls corners off the grid (the RMS
    // doubles). camgeom with the same fixed window, and its adaptive window (capped at the
    // same half side), are pulled the same way: their RMS is OpenCV's to 1 % (0.4066 vs
    // 0.4087). The assertion is that they are no worse; the saddle fit below is the way out.
    let sp11 = SubPixConfig {
        half_window: 11,
        max_iterations: 30,
        epsilon: 0.001,
    };
    let views: Vec<Vec<Point2<f64>>> = names
        .iter()
        .map(|n| detect(n, Refinement::CornerSubPix(sp11)).unwrap())
        .collect();
    let r11 = calibrate::<f64>(&views, &CalibrationConfig::default());
    let views: Vec<Vec<Point2<f64>>> = names
        .iter()
        .map(|n| detect(n, Refinement::AdaptiveCornerSubPix(sp11)).unwrap())
        .collect();
    let ra = calibrate::<f64>(&views, &CalibrationConfig::default());
    let cv11 = opencv_json()["subpix11"]["rms"].as_f64().unwrap();
    println!(
        "winSize (11, 11): camgeom rms {:.4}, adaptive {:.4}, OpenCV {cv11:.4}",
        r11.rms_px, ra.rms_px
    );
    assert!(r11.rms_px <= cv11 && ra.rms_px <= cv11);
    // camgeom's default refinement, the saddle fit.
    let views: Vec<Vec<Point2<f64>>> = names
        .iter()
        .map(|n| detect(n, Refinement::Saddle(SaddleConfig::default())).unwrap())
        .collect();
    let rs = calibrate::<f64>(&views, &CalibrationConfig::default());
    println!("saddle fit: camgeom rms {:.4}: {}", rs.rms_px, summary(&rs));
    assert!(rs.rms_px <= cv);
}
