//! camgeom's chessboard detection on boards rendered by OpenCV at every scale, side by side with
//! OpenCV's detectors on the same images:
//!
//! ```sh
//! python3 host-tests/scripts/render_chessboard_scales.py DIR [SIZE ...]
//! cargo run --release -p camgeom-host --example chessboard_scales DIR
//! ```
//!
//! Per frame size: views found (of those with the whole board in view) and the RMS corner
//! error against the truth (each true corner to the nearest found one) for camgeom's
//! `detect` (one scale) and `detect_any_scale`, and for OpenCV's `findChessboardCorners` +
//! `cornerSubPix` and `findChessboardCornersSB` (read from the script's `opencv.csv`);
//! median time per view. A found board whose corner is more than 2 px off is counted wrong.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use camgeom::chessboard::{
    BoardSize, Chessboard, ChessboardDetector, DetectParams, pyramid_len, scratch_len,
};

#[derive(Default)]
struct Tally {
    views: usize,
    found: usize,
    wrong: usize,
    sq_err: f64,
    corners: usize,
    ms: Vec<f64>,
}

impl Tally {
    fn add(&mut self, rms: Option<f64>, ms: f64) {
        self.views += 1;
        self.ms.push(ms);
        match rms {
            Some(r) if r > 2.0 => self.wrong += 1,
            Some(r) => {
                self.found += 1;
                self.sq_err += r * r;
                self.corners += 1;
            }
            None => {}
        }
    }
    fn cell(&mut self) -> String {
        self.ms.sort_by(f64::total_cmp);
        let med = self.ms.get(self.ms.len() / 2).copied().unwrap_or(0.0);
        let rms = if self.corners > 0 {
            format!("{:.3}", (self.sq_err / self.corners as f64).sqrt())
        } else {
            "-".into()
        };
        let wrong = if self.wrong > 0 {
            format!(" ({} wrong)", self.wrong)
        } else {
            String::new()
        };
        format!(
            "{}/{}{wrong}, {rms} px, {med:.1} ms",
            self.found, self.views
        )
    }
}

fn rms_to_truth(found: &[camgeom::nalgebra::Point2<f32>], truth: &[(f64, f64)]) -> f64 {
    let s: f64 = truth
        .iter()
        .map(|&(u, v)| {
            found
                .iter()
                .map(|p| (f64::from(p.x) - u).powi(2) + (f64::from(p.y) - v).powi(2))
                .fold(f64::INFINITY, f64::min)
        })
        .sum();
    (s / truth.len() as f64).sqrt()
}

fn main() {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .expect("usage: chessboard_scales DIR"),
    );
    let board = BoardSize::new(9, 6).unwrap();
    let mut truth: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut rd = csv::Reader::from_path(dir.join("truth.csv")).expect("truth.csv");
    for r in rd.records() {
        let r = r.unwrap();
        truth
            .entry(r[0].to_string())
            .or_default()
            .push((r[2].parse().unwrap(), r[3].parse().unwrap()));
    }
    let mut rd = csv::Reader::from_path(dir.join("opencv.csv")).expect("opencv.csv");
    let mut cases = Vec::new();
    for r in rd.records() {
        let r = r.unwrap();
        let opt = |i: usize| r[i].parse::<f64>().ok();
        cases.push((
            r[0].to_string(),
            format!("{}x{}", &r[1], &r[2]),
            &r[3] == "1",
            (opt(6), opt(5).unwrap_or(0.0)),
            (opt(9), opt(8).unwrap_or(0.0)),
        ));
    }
    let params = DetectParams::default();
    let mut det = Box::new(ChessboardDetector::<1024>::new());
    let mut rows: BTreeMap<(usize, String), [Tally; 4]> = BTreeMap::new();
    for (name, size, in_view, cv, sb) in cases {
        if !in_view {
            continue;
        }
        let img = camgeom_host::images::load_gray(dir.join(format!("{name}.png"))).unwrap();
        let view = img.view().unwrap();
        let mut scratch = vec![0i32; scratch_len(img.width)];
        let mut pyramid = vec![0u8; pyramid_len(img.width, img.height)];
        let t = &truth[&name];
        let t0 = Instant::now();
        let one: Option<Chessboard<64>> = det.detect(&view, board, &params, &mut scratch).unwrap();
        let one_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now();
        let any: Option<Chessboard<64>> = det
            .detect_any_scale(&view, board, &params, &mut pyramid, &mut scratch)
            .unwrap();
        let any_ms = t0.elapsed().as_secs_f64() * 1e3;
        let key = (img.width * img.height, size);
        let row = rows.entry(key).or_default();
        let one_rms = one.map(|b| rms_to_truth(&b.corners, t));
        let any_rms = any.map(|b| rms_to_truth(&b.corners, t));
        println!(
            "{name}: detect {one_rms:?}, any scale {any_rms:?}, OpenCV {:?}, SB {:?}",
            cv.0, sb.0
        );
        row[0].add(one_rms, one_ms);
        row[1].add(any_rms, any_ms);
        row[2].add(cv.0, cv.1);
        row[3].add(sb.0, sb.1);
    }
    println!();
    println!(
        "| size | camgeom `detect` | camgeom `detect_any_scale` | OpenCV `findChessboardCorners` + `cornerSubPix` | OpenCV `findChessboardCornersSB` |"
    );
    println!("|---|---|---|---|---|");
    for ((_, size), mut t) in rows {
        println!(
            "| {size} | {} | {} | {} | {} |",
            t[0].cell(),
            t[1].cell(),
            t[2].cell(),
            t[3].cell()
        );
    }
}
