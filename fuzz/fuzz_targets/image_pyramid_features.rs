//! Image views of arbitrary geometry over buffers of arbitrary length, Gaussian pyramids into
//! buffers of arbitrary length, Shi-Tomasi corners with arbitrary parameters and scratch, the
//! view warped into a frame through an arbitrary quadrilateral and an arbitrary homography in
//! both arithmetics.
//! Contract: no panic; a view exists only for a valid geometry; a pyramid's levels have the
//! documented sizes; corners lie inside the image and respect the output capacity; a warp
//! writes at most the frame's pixels.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::corners::{Corner, CornerConfig, good_features};
use camgeom::heapless::Vec;
use camgeom::homography::Homography;
use camgeom::image::{ImageMut, ImageView, buffer_len};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::pyramid::{self, Pyramid};
use camgeom::warp::{Arithmetic, WarpConfig, warp_into_quad, warp_perspective_into};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    width: u16,
    height: u16,
    stride: u16,
    /// Buffer length minus the length the geometry needs (may be negative).
    slack: i16,
    levels: u8,
    pyr_slack: i16,
    quality: f32,
    min_distance: u16,
    max_corners: u8,
    candidates: u8,
    scratch_slack: i16,
    existing: [(u8, u8); 3],
    seed: u32,
    quad: [(f32, f32); 4],
    /// A homography for `warp_perspective_into` (any matrix `from_matrix` accepts).
    map: [f32; 9],
    alpha: u8,
}

fn grow(len: usize, slack: i16) -> usize {
    (len as i64 + i64::from(slack)).clamp(0, 1 << 17) as usize
}

fuzz_target!(|inp: Input| {
    // Any geometry (the size checks see zero, huge and odd values), but at most 64 KiB of
    // pixels: larger geometries meet a buffer that is too short, and each run stays short.
    let (w, h, s) = (
        usize::from(inp.width),
        usize::from(inp.height),
        usize::from(inp.stride),
    );
    let need = buffer_len(w, h, s);
    let len = grow(need.min(1 << 16), inp.slack);
    let mut state = inp.seed | 1;
    let data: std::vec::Vec<u8> = (0..len)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            // Smooth ramps and noise: corners exist.
            (state as u8 & 0x3f).wrapping_add(((i % 97) * 2) as u8)
        })
        .collect();
    let Ok(view) = ImageView::new(&data[..], w, h, s) else {
        return;
    };
    assert!(
        w > 0 && h > 0 && s >= w && data.len() >= need,
        "view accepted a bad geometry"
    );
    assert_eq!((view.width(), view.height(), view.stride()), (w, h, s));

    let levels = usize::from(inp.levels % 10);
    let mut pbuf = std::vec![0u8; grow(pyramid::buffer_len(w, h, levels.min(8)), inp.pyr_slack)];
    if let Ok(p) = Pyramid::build(view, &mut pbuf[..], levels) {
        assert!(
            !p.is_empty() && p.len() <= levels.max(1),
            "pyramid level count"
        );
        for l in 0..p.len() {
            let lv = p.level(l).expect("level below len() exists");
            assert_eq!(
                (lv.width(), lv.height()),
                pyramid::level_size(w, h, l),
                "level {l} size"
            );
        }
        assert!(p.level(p.len()).is_none());
    }

    let cfg = CornerConfig {
        quality: inp.quality,
        min_distance: u32::from(inp.min_distance),
        max_corners: usize::from(inp.max_corners),
    };
    let mut cand = std::vec![Corner::default(); usize::from(inp.candidates)];
    let mut scratch = std::vec![0u32; grow(camgeom::corners::scratch_len(w), inp.scratch_slack)];
    let existing = inp.existing.map(|(x, y)| [i32::from(x), i32::from(y)]);
    let mut out: Vec<Corner, 16> = Vec::new();
    if let Ok(n) = good_features(
        &view,
        &cfg,
        existing.iter().copied(),
        &mut out,
        &mut cand[..],
        &mut scratch[..],
    ) {
        assert_eq!(n, out.len(), "count returned");
        for c in &out {
            assert!(
                usize::from(c.x) < w && usize::from(c.y) < h,
                "corner outside the image"
            );
        }
        if cfg.max_corners > 0 {
            assert!(n <= cfg.max_corners);
        }
    }

    let quad = inp.quad.map(|(x, y)| Point2::new(x, y));
    for arithmetic in [Arithmetic::Float, Arithmetic::Fixed] {
        let mut frame = [0u8; 64 * 48];
        let Ok(mut dst) = ImageMut::packed(&mut frame[..], 64, 48) else {
            return;
        };
        let cfg = WarpConfig {
            alpha: inp.alpha,
            arithmetic,
        };
        if let Ok(r) = warp_into_quad(&view, &mut dst, &quad, &cfg) {
            assert!(r.written <= 64 * 48, "written beyond the frame");
        }
        if let Ok(map) = Homography::from_matrix(&Matrix3::from_row_slice(&inp.map))
            && let Ok(r) = warp_perspective_into(&view, &mut dst, &map, &cfg)
        {
            assert!(r.written <= 64 * 48, "written beyond the frame");
        }
    }
});
