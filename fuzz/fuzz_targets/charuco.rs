//! ChArUco corners (`charuco::interpolate_corners`): a board from arbitrary bytes (any number
//! of squares, sizes non-finite, negative or huge included, four dictionaries), an image of up
//! to 96x96 that is often the board drawn through an arbitrary affine map (squares by parity,
//! markers from the fuzzer's bytes, noise) and otherwise any bytes, and up to 16 detections:
//! often the board's own markers through the same map, each corner moved by the fuzzer, so
//! the prediction, the two markers' agreement test and the saddle refinement run past their
//! checks; otherwise any family, id and corners. Options from the fuzzer too.
//!
//! Contract (`CharucoBoard::new`, `CharucoConfig::check`, `interpolate_corners` docs): no
//! panic; with an `out` shorter than the board's corners `BufferTooSmall`; otherwise a count
//! no larger than the board's corners, ids strictly increasing and on the board, every point
//! finite and inside the image.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::apriltag::{Family, families};
use camgeom::charuco::{CharucoBoard, CharucoConfig, CharucoCorner, interpolate_corners};
use camgeom::chessboard::SaddleConfig;
use camgeom::image::ImageView;
use camgeom::nalgebra::Point2;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Num, detection};

const FAMILIES: [&Family; 4] = [
    &families::DICT_4X4_50,
    &families::DICT_5X5_100,
    &families::DICT_6X6_250,
    &families::TAG36H11,
];

#[derive(Debug, Arbitrary)]
enum Det {
    /// Board marker `k` through the map, each corner moved by the fuzzer's pixels.
    Projected { k: u8, moves: [(i8, i8); 4] },
    /// Anything.
    Free {
        family: u8,
        id: u16,
        corners: [(Num, Num); 4],
    },
}

#[derive(Debug, Arbitrary)]
struct Input {
    squares: (u8, u8),
    square: Num,
    marker: Num,
    family: u8,
    size: (u8, u8),
    /// The map board -> pixel: pixels per unit, angle (1/256 turn), offset.
    scale: Num,
    angle: u8,
    offset: (i8, i8),
    /// Drawn board (true) or raw bytes (false).
    drawn: bool,
    bytes: Vec<u8>,
    dets: Vec<Det>,
    min_markers: u8,
    max_shift: Num,
    half_window: u8,
    sigma: Num,
    max_iterations: u8,
    short_out: bool,
}

fuzz_target!(|inp: Input| {
    let family = FAMILIES[usize::from(inp.family) % FAMILIES.len()];
    let (sx, sy) = (
        usize::from(inp.squares.0 % 16),
        usize::from(inp.squares.1 % 16),
    );
    let board = match CharucoBoard::new(sx, sy, inp.square.get(), inp.marker.get(), family) {
        Ok(b) => b,
        Err(e) => {
            assert!(matches!(e, Error::InvalidParameter(_)), "{e:?}");
            return;
        }
    };
    let cfg = CharucoConfig {
        min_markers: inp.min_markers % 4,
        max_shift: inp.max_shift.get(),
        saddle: SaddleConfig {
            half_window: inp.half_window % 12,
            sigma: inp.sigma.get(),
            max_iterations: inp.max_iterations % 40,
            ..SaddleConfig::default()
        },
    };
    let params = match cfg.check() {
        Ok(p) => p,
        Err(_) => camgeom::charuco::CharucoParams::default(),
    };

    let (w, h) = (usize::from(inp.size.0 % 97), usize::from(inp.size.1 % 97));
    // Board -> pixel: p = s R b + t.
    let s = inp.scale.get();
    let a = f32::from(inp.angle) * std::f32::consts::TAU / 256.0;
    let (c, sn) = (a.cos(), a.sin());
    let t = (f32::from(inp.offset.0), f32::from(inp.offset.1));
    let map = |b: Point2<f32>| {
        Point2::new(
            s * (c * b.x - sn * b.y) + t.0,
            s * (sn * b.x + c * b.y) + t.1,
        )
    };
    let byte = |i: usize| {
        inp.bytes
            .get(i % inp.bytes.len().max(1))
            .copied()
            .unwrap_or(0)
    };
    let mut pixels = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            pixels[i] = if inp.drawn && s.is_finite() && s != 0.0 {
                // Pixel -> board: b = Rᵀ (p - t) / s.
                let (px, py) = (x as f32 - t.0, y as f32 - t.1);
                let (bx, by) = ((c * px + sn * py) / s, (-sn * px + c * py) / s);
                let q = board.square();
                let (col, row) = ((bx / q).floor(), (by / q).floor());
                let black = ((col as i64) ^ (row as i64)) & 1 == 0;
                let noise = byte(i) & 0x1f;
                if black { noise } else { 0xe0 | noise }
            } else {
                byte(i)
            };
        }
    }
    let Ok(view) = ImageView::new(&pixels, w, h, w) else {
        return;
    };

    let mut dets = Vec::new();
    for d in inp.dets.iter().take(16) {
        match d {
            Det::Projected { k, moves } => {
                let id = usize::from(*k) % board.markers().max(1);
                let Some(mc) = board.marker_corners(id) else {
                    continue;
                };
                let mut p = [Point2::origin(); 4];
                for ((p, b), m) in p.iter_mut().zip(mc).zip(moves) {
                    let q = map(b);
                    *p = Point2::new(q.x + f32::from(m.0) / 16.0, q.y + f32::from(m.1) / 16.0);
                }
                dets.push(detection(family, id as u16, p));
            }
            Det::Free {
                family,
                id,
                corners,
            } => {
                let f = FAMILIES[usize::from(*family) % FAMILIES.len()];
                let p = corners.map(|(x, y)| Point2::new(x.get(), y.get()));
                dets.push(detection(f, *id, p));
            }
        }
    }

    let n = board.corners();
    let mut out = vec![
        CharucoCorner::default();
        if inp.short_out {
            n.saturating_sub(1)
        } else {
            n
        }
    ];
    match interpolate_corners(&board, &view, &dets, &params, &mut out) {
        Ok(k) => {
            assert!(!inp.short_out || n == 0, "short buffer accepted");
            assert!(k <= n, "{k} > {n}");
            let mut last = None;
            for corner in &out[..k] {
                assert!(usize::from(corner.id) < n, "{corner:?}");
                assert!(
                    last.is_none_or(|l| l < corner.id),
                    "ids not increasing: {corner:?}"
                );
                last = Some(corner.id);
                let p = corner.point;
                assert!(p.x.is_finite() && p.y.is_finite(), "{corner:?}");
                assert!(
                    p.x >= 0.0 && p.y >= 0.0 && p.x <= w as f32 - 1.0 && p.y <= h as f32 - 1.0,
                    "{corner:?} outside {w}x{h}"
                );
            }
        }
        Err(e) => assert!(
            inp.short_out && matches!(e, Error::BufferTooSmall("corners")),
            "{e:?}"
        ),
    }
});
