//! Chessboard corners on boards rendered by OpenCV with exact sub-pixel truth
//! (`make_calib_fixtures.py rendered`): rotation, strong perspective, uneven light, the board
//! at the border, blur and noise, Brown-Conrady and fisheye lenses, a small board, and two
//! negatives (board partly out of view, no board). camgeom against OpenCV's
//! `findChessboardCorners` + `cornerSubPix` and `findChessboardCornersSB` on the same frames.

use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SaddleConfig, SubPixConfig,
    scratch_len,
};
use camgeom::nalgebra::Point2;

fn dir() -> std::path::PathBuf {
    camgeom_host::data_dir().join("fixtures/calib")
}

struct Case {
    name: String,
    size: (usize, usize),
    board: (usize, usize),
    in_view: bool,
    half: u8,
    truth: Vec<Point2<f64>>,
    cv: Option<Vec<Point2<f64>>>,
    sb: Option<Vec<Point2<f64>>>,
    cv_index: Vec<Option<usize>>,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(dir().join("rendered_cases.csv")).unwrap();
    let mut out: Vec<Case> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let n = |i: usize| f[i].parse::<usize>().unwrap();
            Case {
                name: f[0].into(),
                size: (n(1), n(2)),
                board: (n(3), n(4)),
                in_view: n(5) == 1,
                half: n(6) as u8,
                truth: vec![],
                cv: (n(7) == 1).then(Vec::new),
                sb: (n(8) == 1).then(Vec::new),
                cv_index: vec![],
            }
        })
        .collect();
    let text = std::fs::read_to_string(dir().join("rendered.csv")).unwrap();
    for l in text.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        let c = out.iter_mut().find(|c| c.name == f[0]).unwrap();
        let p = |i: usize| Point2::new(f[i].parse().unwrap(), f[i + 1].parse().unwrap());
        c.truth.push(p(2));
        if let Some(v) = c.cv.as_mut() {
            v.push(p(4));
        }
        if let Some(v) = c.sb.as_mut() {
            v.push(p(6));
        }
        c.cv_index.push(f[8].parse().ok());
    }
    out
}

fn stats(e: &[f64]) -> (f64, f64) {
    let mut v = e.to_vec();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    (v[v.len() / 2], *v.last().unwrap())
}

/// Distance from each truth corner to the nearest detected corner, and that corner's index.
fn errors(truth: &[Point2<f64>], found: &[Point2<f64>]) -> (Vec<f64>, Vec<usize>) {
    truth
        .iter()
        .map(|t| {
            let (i, d) = found
                .iter()
                .enumerate()
                .map(|(i, p)| (i, (p - t).norm()))
                .min_by(|a, b| a.1.partial_cmp(&b.1).unwrap())
                .unwrap();
            (d, i)
        })
        .unzip()
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Variant {
    /// OpenCV's settings: `cornerSubPix` with one window (11x11 at 640x480, 7x7 at 320x240).
    OpenCvWindow,
    /// `cornerSubPix`, window up to 15x15 shrunk to half the local corner spacing.
    Adaptive,
    /// camgeom's default: the saddle point of the smoothed image.
    Saddle,
}

#[test]
fn rendered_boards_against_truth_and_opencv() {
    for v in [Variant::OpenCvWindow, Variant::Adaptive, Variant::Saddle] {
        println!("refinement: {v:?}");
        run(v);
    }
}

fn run(variant: Variant) {
    println!(
        "case         | camgeom median/max px | OpenCV classic median/max | OpenCV SB median/max"
    );
    for c in cases() {
        let img = camgeom_host::images::load_gray(dir().join(format!("rendered/{}.png", c.name)))
            .unwrap();
        assert_eq!((img.width, img.height), c.size);
        let mut det = Box::new(ChessboardDetector::<512>::new());
        let mut scratch = vec![0i32; scratch_len(img.width)];
        let sp = |half_window| SubPixConfig {
            half_window,
            max_iterations: 30,
            // Run to convergence: OpenCV's 0.001 compares the squared step, so it stops up
            // to 0.03 px early and the result then depends on where the iteration started;
            // converged, camgeom's fixed-window corners are OpenCV's to 0.001 px.
            epsilon: 1e-8,
        };
        let refine = match variant {
            Variant::OpenCvWindow => Refinement::CornerSubPix(sp(c.half)),
            Variant::Adaptive => Refinement::AdaptiveCornerSubPix(sp(7)),
            Variant::Saddle => Refinement::Saddle(SaddleConfig::default()),
        };
        let params = DetectConfig {
            refine,
            ..DetectConfig::default()
        }
        .check()
        .unwrap();
        let board = BoardSize::new(c.board.0, c.board.1).unwrap();
        let found = det
            .detect::<100>(&img.view().unwrap(), board, &params, &mut scratch)
            .unwrap()
            .map(|b| {
                b.corners
                    .iter()
                    .map(|p| p.cast::<f64>())
                    .collect::<Vec<_>>()
            });
        let fmt = |v: Option<(f64, f64)>| {
            v.map_or("not found".to_string(), |(m, x)| format!("{m:.4} / {x:.4}"))
        };
        let ours = found.as_ref().map(|f| errors(&c.truth, f));
        let cv = c.cv.as_ref().map(|f| stats(&errors(&c.truth, f).0));
        let sb = c.sb.as_ref().map(|f| stats(&errors(&c.truth, f).0));
        println!(
            "{:12} | {:21} | {:25} | {}",
            c.name,
            fmt(ours.as_ref().map(|o| stats(&o.0))),
            fmt(cv),
            fmt(sb)
        );
        if !c.in_view {
            assert!(
                found.is_none(),
                "{}: a board not entirely in view must not be found",
                c.name
            );
            continue;
        }
        let (e, order) = ours.unwrap_or_else(|| panic!("{}: not found", c.name));
        let (med, max) = stats(&e);
        // Same order as OpenCV wherever OpenCV finds the board: truth corner k is camgeom's
        // corner cv_index[k].
        if c.cv.is_some() {
            for (k, (o, ci)) in order.iter().zip(&c.cv_index).enumerate() {
                assert_eq!(
                    Some(*o),
                    *ci,
                    "{}: corner {k} out of OpenCV's order",
                    c.name
                );
            }
        } else {
            // Truth order is the board's own (row-major from the corner OpenCV starts at on
            // these renders); camgeom must follow it.
            assert!(
                order.iter().enumerate().all(|(k, o)| k == *o),
                "{}: order",
                c.name
            );
        }
        // No worse than OpenCV's classic detector + cornerSubPix, within 0.002 px (median) and
        // 0.01 px (max): with the same window both converge to the same point of the same
        // gradient-orthogonality iteration (measured at most 0.0006 px apart, sweep225); the
        // adaptive window is better on all but one (perspective, 0.0015 px worse); the
        // saddle fit is better on all.
        if let Some((cm, cx)) = cv {
            assert!(med <= cm + 0.002, "{}: median {med} vs OpenCV {cm}", c.name);
            assert!(max <= cx + 0.01, "{}: max {max} vs OpenCV {cx}", c.name);
        }
        if variant == Variant::Saddle {
            // The saddle fit: no worse than SB either, where SB finds the board (median and
            // max, same 0.002 / 0.01 px slack; measured better on every board).
            if let Some((sm, sx)) = sb {
                assert!(
                    med <= sm + 0.002 && max <= sx + 0.01,
                    "{}: {med} {max} vs SB {sm} {sx}",
                    c.name
                );
            }
        }
        assert!(max < 0.5, "{}: max {max}", c.name);
    }
}
