//! Chessboard detection on frames of arbitrary geometry (zero, tiny, huge-claimed sizes,
//! strides, buffers shorter or longer than the geometry needs) holding a rendered board
//! (arbitrary placement, rotation, shear, square size, contrast, noise) or arbitrary bytes,
//! with arbitrary board sizes, scratch and configurations (every refinement); then
//! `corner_subpix` and `saddle_subpix` on arbitrary corners. Contract (module and `detect`
//! docs): no panic; `Ok(Some)` holds exactly `cols · rows` corners of the board asked for,
//! finite, inside the frame, in OpenCV's order (`(p[cols-1] - p[0]) × (p[cols] - p[cols-1])
//! ≥ 0`); the documented errors for a small frame, scratch or corner buffer; the refiners'
//! `Ok` corners are finite.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::chessboard::{
    BoardSize, ChessboardDetector, DetectConfig, Refinement, SaddleConfig, SubPixConfig,
    corner_subpix, pyramid_len, saddle_subpix, scratch_len,
};
use camgeom::image::ImageView;
use camgeom::nalgebra::Point2;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Geometry, Num};

/// Corners a detection can return (a board asking for more is `BufferTooSmall`).
const N: usize = 200;

#[derive(Debug, Arbitrary)]
enum Scene {
    /// The board asked for (plus one square each way when `extra % 4 == 3`: a larger
    /// pattern) rendered through an affine map.
    Board {
        extra: (u8, u8),
        /// Side of a square, pixels: 4 + (square % 28).
        square: u8,
        origin: (u8, u8),
        /// Rotation, 1/256 turns.
        angle: u8,
        /// Shear and anisotropy, 1/64 steps around 1.
        shear: i8,
        aspect: i8,
        dark: u8,
        light: u8,
        /// Noise amplitude (grey levels).
        noise: u8,
        /// Swap dark and light squares.
        invert: bool,
    },
    /// The fuzzer's bytes, tiled.
    Bytes(std::vec::Vec<u8>),
}

#[derive(Debug, Arbitrary)]
enum Refine {
    None,
    CornerSubPix(u8, u8, Num),
    Adaptive(u8, u8, Num),
    Saddle(u8, Num, u8, Num),
}

#[derive(Debug, Arbitrary)]
struct Cfg {
    min_response: i16,
    min_contrast: u8,
    max_seeds: u8,
    refine: Refine,
}

#[derive(Debug, Arbitrary)]
struct Input {
    geometry: Geometry,
    scene: Scene,
    seed: u32,
    board: (u8, u8),
    scratch_slack: i16,
    /// `None`: the defaults (so that most runs detect something).
    cfg: Option<Cfg>,
    /// With the default thresholds: the refinement (`None`: the default, the saddle point),
    /// so that every refinement meets detected boards.
    refine: Option<Refine>,
    corners: std::vec::Vec<(Num, Num)>,
}

fn refinement(r: &Refine) -> Refinement {
    let sub = |h: u8, it: u8, eps: Num| SubPixConfig {
        half_window: h,
        max_iterations: it,
        epsilon: eps.get(),
    };
    match *r {
        Refine::None => Refinement::None,
        Refine::CornerSubPix(h, it, e) => Refinement::CornerSubPix(sub(h, it, e)),
        Refine::Adaptive(h, it, e) => Refinement::AdaptiveCornerSubPix(sub(h, it, e)),
        Refine::Saddle(h, s, it, e) => Refinement::Saddle(SaddleConfig {
            half_window: h,
            sigma: s.get(),
            max_iterations: it,
            epsilon: e.get(),
        }),
    }
}

fn config(c: &Option<Cfg>, refine: &Option<Refine>) -> DetectConfig {
    let Some(c) = c else {
        let d = DetectConfig::default();
        return DetectConfig {
            refine: refine.as_ref().map_or(d.refine, refinement),
            ..d
        };
    };
    DetectConfig {
        min_response: i32::from(c.min_response),
        min_contrast: c.min_contrast,
        max_seeds: c.max_seeds,
        refine: refinement(&c.refine),
    }
}

/// The frame's pixels: `len` bytes laid out with `stride`.
fn render(
    scene: &Scene,
    board: (u8, u8),
    stride: usize,
    len: usize,
    seed: u32,
) -> std::vec::Vec<u8> {
    let mut state = seed | 1;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let stride = stride.max(1);
    (0..len)
        .map(|i| {
            let (x, y) = ((i % stride) as f32, (i / stride) as f32);
            match scene {
                Scene::Bytes(b) => b.get(i % b.len().max(1)).copied().unwrap_or(0),
                Scene::Board {
                    extra,
                    square,
                    origin,
                    angle,
                    shear,
                    aspect,
                    dark,
                    light,
                    noise: amp,
                    invert,
                } => {
                    let s = 4.0 + f32::from(square % 28);
                    let t = f32::from(*angle) / 256.0 * std::f32::consts::TAU;
                    let (c, sn) = (t.cos(), t.sin());
                    let (dx, dy) = (x - f32::from(origin.0), y - f32::from(origin.1));
                    // Board coordinates: rotate back, then undo shear and aspect.
                    let (u, v) = (c * dx + sn * dy, -sn * dx + c * dy);
                    let u = u * (1.0 + f32::from(*aspect) / 64.0) + v * f32::from(*shear) / 64.0;
                    let (i, j) = ((u / s).floor(), (v / s).floor());
                    let squares = |b: u8, e: u8| f32::from(b.min(24) + 1 + u8::from(e % 4 == 3));
                    let (sq_c, sq_r) = (squares(board.0, extra.0), squares(board.1, extra.1));
                    let inside = i >= 0.0 && j >= 0.0 && i < sq_c && j < sq_r;
                    let black = inside && ((i + j) as i64 % 2 == 0) != *invert;
                    let base = if black { *dark } else { *light };
                    let a = u32::from(*amp % 64) + 1;
                    base.wrapping_add((noise() % a) as u8)
                }
            }
        })
        .collect()
}

fuzz_target!(|inp: Input| {
    // Any geometry, at most 64 K pixels of buffer: larger geometries meet a short buffer.
    let (w, h, s, len) = inp.geometry.dims(1 << 16);
    let data = render(&inp.scene, inp.board, s, len, inp.seed);
    let cfg = config(&inp.cfg, &inp.refine);
    let mut det = ChessboardDetector::<128>::new();
    if let (Ok(view), Ok(board)) = (
        ImageView::new(&data[..], w, h, s),
        BoardSize::new(usize::from(inp.board.0), usize::from(inp.board.1)),
    ) {
        let scratch_n = (scratch_len(w) as i64 + i64::from(inp.scratch_slack)).max(0) as usize;
        let mut scratch = std::vec![0i32; scratch_n];
        let detected = cfg
            .check()
            .and_then(|params| det.detect::<N>(&view, board, &params, &mut scratch));
        match &detected {
            Ok(Some(found)) => {
                let cols = board.cols();
                assert_eq!(found.size, board, "board size");
                assert_eq!(found.corners.len(), board.corners(), "corner count");
                for p in &found.corners {
                    assert!(p.x.is_finite() && p.y.is_finite(), "corner not finite");
                    assert!(
                        p.x >= -0.5
                            && p.y >= -0.5
                            && p.x <= w as f32 - 0.5
                            && p.y <= h as f32 - 0.5,
                        "corner {p:?} outside the {w}x{h} frame"
                    );
                }
                let c = &found.corners;
                let (a, b, d) = (c[0], c[cols - 1], c[cols]);
                let (e1, e2) = (b - a, d - b);
                let cross = e1.x * e2.y - e1.y * e2.x;
                assert!(cross >= 0.0, "corner order: cross product {cross}");
            }
            Ok(None) => {}
            Err(Error::InvalidImage) => assert!(w < 16 || h < 16, "InvalidImage for {w}x{h}"),
            Err(Error::BufferTooSmall("scratch")) => assert!(scratch_n < scratch_len(w)),
            Err(Error::BufferTooSmall("corners")) => assert!(board.corners() > N),
            // Only the check names a parameter; detect takes it checked.
            Err(Error::InvalidParameter(_)) => assert!(cfg.check().is_err()),
            Err(e) => panic!("detect: undocumented error {e:?}"),
        }

        // The same frame at any scale: the same contract, and it finds whatever the
        // one-scale search found (the frame itself is its last level).
        let pyr_n = (pyramid_len(w, h) as i64 + i64::from(inp.scratch_slack)).max(0) as usize;
        let mut pyramid = std::vec![0u8; pyr_n];
        let any = cfg.check().and_then(|params| {
            det.detect_any_scale::<N>(&view, board, &params, &mut pyramid, &mut scratch)
        });
        match any {
            Ok(Some(found)) => {
                assert_eq!(
                    found.corners.len(),
                    board.corners(),
                    "any scale: corner count"
                );
                for p in &found.corners {
                    assert!(p.x.is_finite() && p.y.is_finite(), "any scale: not finite");
                }
            }
            Ok(None) => assert!(
                !matches!(detected, Ok(Some(_))),
                "any scale lost a board the one-scale search found"
            ),
            Err(Error::InvalidImage) => assert!(w < 16 || h < 16, "InvalidImage for {w}x{h}"),
            Err(Error::BufferTooSmall("scratch")) => assert!(scratch_n < scratch_len(w)),
            Err(Error::BufferTooSmall("pyramid")) => assert!(pyr_n < pyramid_len(w, h)),
            Err(Error::BufferTooSmall("corners")) => assert!(board.corners() > N),
            Err(Error::InvalidParameter(_)) => assert!(cfg.check().is_err()),
            Err(e) => panic!("detect_any_scale: undocumented error {e:?}"),
        }

        // The refiners on arbitrary corners.
        let mut pts: std::vec::Vec<Point2<f32>> = inp
            .corners
            .iter()
            .take(8)
            .map(|&(x, y)| Point2::new(x.get(), y.get()))
            .collect();
        let mut pts2 = pts.clone();
        if let Refinement::CornerSubPix(sp) | Refinement::AdaptiveCornerSubPix(sp) = cfg.refine
            && let Ok(sp) = sp.check()
            && corner_subpix(&view, &mut pts, &sp).is_ok()
        {
            assert!(common::finite(&flat(&pts)), "corner_subpix: not finite");
        }
        let sc = match cfg.refine {
            Refinement::Saddle(sc) => sc,
            _ => SaddleConfig::default(),
        };
        if let Ok(sc) = sc.check()
            && saddle_subpix(&view, &mut pts2, &sc).is_ok()
        {
            assert!(common::finite(&flat(&pts2)), "saddle_subpix: not finite");
        }
    }
});

fn flat(p: &[Point2<f32>]) -> std::vec::Vec<f32> {
    p.iter().flat_map(|q| [q.x, q.y]).collect()
}
