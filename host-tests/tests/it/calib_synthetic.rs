//! Calibration with exact ground truth: known boards projected by OpenCV through known
//! cameras (Brown-Conrady and fisheye), with noise of 0, 0.1, 0.5 and 1 px, calibrated by
//! camgeom and by OpenCV (`cv2.calibrateCamera`, `cv2.fisheye.calibrate`) on the same points
//! (`host-tests/scripts/make_calib_fixtures.py synthetic`).

use std::collections::BTreeMap;

use camgeom::Real;
use camgeom::calib::{CalibrationConfig, CalibrationReport, Calibrator};
use camgeom::camera::{Lens, LensModel};
use camgeom::chessboard::BoardSize;
use camgeom::nalgebra::Point2;

type Views = BTreeMap<(String, String), Vec<Vec<Point2<f64>>>>;

fn load() -> (Views, serde_json::Value) {
    let dir = camgeom_host::data_dir().join("fixtures/calib");
    let text = std::fs::read_to_string(dir.join("synthetic.csv")).unwrap();
    let mut views: Views = BTreeMap::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let key = (f[0].to_string(), f[1].to_string());
        let v: usize = f[2].parse().unwrap();
        let e = views.entry(key).or_default();
        if e.len() <= v {
            e.push(vec![]);
        }
        e[v].push(Point2::new(f[4].parse().unwrap(), f[5].parse().unwrap()));
    }
    let json = std::fs::read_to_string(dir.join("synthetic_opencv.json")).unwrap();
    (views, serde_json::from_str(&json).unwrap())
}

fn calibrate<T: Real>(views: &[Vec<Point2<f64>>], model: LensModel) -> CalibrationReport<T, 32> {
    let board = BoardSize::new(9, 6).unwrap();
    let mut cal = Box::new(Calibrator::<T, 32, 100>::new(board, T::lit(0.025), 640, 480).unwrap());
    for v in views {
        let px: Vec<Point2<T>> = v
            .iter()
            .map(|p| Point2::new(T::lit(p.x), T::lit(p.y)))
            .collect();
        cal.add_view(640, 480, &px).unwrap();
    }
    let cfg = CalibrationConfig {
        model,
        max_iterations: 100,
        ..CalibrationConfig::default()
    };
    cal.solve(&cfg.check().unwrap()).unwrap()
}

fn params<T: Real>(r: &CalibrationReport<T, 32>) -> (Vec<f64>, Vec<f64>) {
    let k = &r.camera.intrinsics;
    let kk = vec![k.fx(), k.fy(), k.cx(), k.cy()]
        .into_iter()
        .map(|x| x.to_f64())
        .collect();
    let d = match r.camera.lens {
        Lens::BrownConrady(d) => d.to_opencv().iter().map(|x| x.to_f64()).collect(),
        Lens::KannalaBrandt(f) => f.to_opencv().iter().map(|x| x.to_f64()).collect(),
    };
    (kk, d)
}

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn json_vec(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn recovers_known_cameras_as_well_as_opencv() {
    let (views, cv) = load();
    println!(
        "model   noise | camgeom f64: rms, max |K err| px, max |dist err| | f32 max |K err| | OpenCV: rms, max |K err|, max |dist err|"
    );
    for ((model, noise), v) in &views {
        let kind = if model == "brown" {
            LensModel::BrownConrady
        } else {
            LensModel::KannalaBrandt
        };
        let truth = &cv[model]["truth"];
        let (kt, dt) = (json_vec(&truth["K"]), json_vec(&truth["dist"]));
        let r64 = calibrate::<f64>(v, kind);
        let r32 = calibrate::<f32>(v, kind);
        let (k64, d64) = params(&r64);
        let (k32, _) = params(&r32);
        let o = &cv[model][noise];
        let (ko, dout) = (json_vec(&o["K"]), json_vec(&o["dist"]));
        let orms = o["rms"].as_f64().unwrap();
        println!(
            "{model:7} {noise:5} | {:.5} {:.4} {:.5} | {:.4} | {:.5} {:.4} {:.5}",
            r64.rms_px,
            max_err(&k64, &kt),
            max_err(&d64, &dt),
            max_err(&k32, &kt),
            orms,
            max_err(&ko, &kt),
            max_err(&dout, &dt),
        );
        if model == "fisheye" {
            use camgeom::camera::{Camera, Fisheye, Intrinsics};
            let g = Camera::fisheye(
                Intrinsics::new(ko[0], ko[1], ko[2], ko[3]).unwrap(),
                Fisheye::from_opencv([dout[0], dout[1], dout[2], dout[3]]).unwrap(),
            );
            let board = BoardSize::new(9, 6).unwrap();
            let mut cal =
                Box::new(Calibrator::<f64, 32, 100>::new(board, 0.025, 640, 480).unwrap());
            for vv in v {
                cal.add_view(640, 480, vv).unwrap();
            }
            let cfg = CalibrationConfig {
                model: kind,
                max_iterations: 100,
                ..CalibrationConfig::default()
            };
            // Started at OpenCV's answer, camgeom stays in that minimum: the two cost functions
            // are the same (to the stopping rules' 1e-9 px).
            let rg = cal.solve_with_guess(&cfg.check().unwrap(), &g).unwrap();
            assert!((rg.rms_px - orms).abs() < 1e-9, "{} vs {orms}", rg.rms_px);
        }
        let noise: f64 = noise.parse().unwrap();
        if noise == 0.0 {
            // Exact data: the truth is the minimum. f64 reaches it to 1e-6 px; f32 to the
            // rounding of its normalised pixels (6e-8 · 640 px) amplified by the conditioning.
            assert!(
                max_err(&k64, &kt) < 1e-6 && max_err(&d64, &dt) < 1e-6,
                "{model}"
            );
            assert!(max_err(&k32, &kt) < 0.05, "{model} f32");
        } else {
            // The same cost function as OpenCV's: camgeom must reach a minimum at least as
            // low (1e-6 px of slack for the stopping rules), in f64 and in f32 (1e-4 px).
            assert!(
                r64.rms_px <= orms + 1e-6,
                "{model} {noise}: {} vs {orms}",
                r64.rms_px
            );
            assert!((r32.rms_px as f64) <= orms + 1e-4, "{model} {noise} f32");
        }
    }
}
