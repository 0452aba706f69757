//! One 640x480 chessboard detection and one 13-view calibration, for instruction counts
//! (`docs/notes/calibration.md`):
//!
//! ```sh
//! cargo build --release -p camgeom-host --example calib_count
//! valgrind --tool=callgrind --toggle-collect='*ChessboardDetector*detect*' \
//!     target/release/examples/calib_count detect [cornersubpix]
//! valgrind --tool=callgrind --toggle-collect='*Calibrator*solve*' \
//!     target/release/examples/calib_count calibrate
//! ```

use camgeom::calib::{CalibrationParams, Calibrator};
use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SaddleConfig, SubPixConfig,
    scratch_len,
};
use camgeom::nalgebra::Point2;

fn main() {
    let mode = std::env::args().nth(1).unwrap_or_else(|| "detect".into());
    let data = camgeom_host::data_dir();
    let board = BoardSize::new(9, 6).unwrap();
    if mode == "detect" {
        let img = camgeom_host::images::load_gray(data.join("chessboard/left01.jpg")).unwrap();
        let mut det = Box::new(ChessboardDetector::<512>::new());
        let mut scratch = vec![0i32; scratch_len(img.width)];
        let refine = if std::env::args().nth(2).as_deref() == Some("cornersubpix") {
            Refinement::CornerSubPix(SubPixConfig {
                half_window: 5,
                max_iterations: 30,
                epsilon: 0.1,
            })
        } else {
            Refinement::Saddle(SaddleConfig::default())
        };
        let params = DetectConfig {
            refine,
            ..DetectConfig::default()
        }
        .check()
        .unwrap();
        let found = det
            .detect::<54>(&img.view().unwrap(), board, &params, &mut scratch)
            .unwrap();
        println!("found: {}", found.is_some());
    } else {
        let text = std::fs::read_to_string(data.join("fixtures/calib/real_corners.csv")).unwrap();
        let mut views: Vec<Vec<Point2<f32>>> = vec![];
        let mut last = String::new();
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            if f[0] != last {
                views.push(vec![]);
                last = f[0].to_string();
            }
            let p = Point2::new(f[4].parse().unwrap(), f[5].parse().unwrap());
            views.last_mut().unwrap().push(p);
        }
        let mut cal = Box::new(Calibrator::<f32, 32, 100>::new(board, 0.025, 640, 480).unwrap());
        for v in &views {
            cal.add_view(640, 480, v).unwrap();
        }
        let r = cal.solve(&CalibrationParams::default()).unwrap();
        println!("rms {} px after {} steps", r.rms_px, r.iterations);
    }
}
