//! Chessboards at any resolution: the 13 bundled 640x480 views enlarged 2x and 3x (bilinear,
//! the `image` crate's), found by `detect_any_scale` in OpenCV's order at OpenCV's corners
//! (its `findChessboardCorners` + `cornerSubPix` on the original views, mapped by the
//! enlargement `x' = s (x + 1/2) - 1/2`). The one-scale `detect` loses most of them at 3x:
//! the enlargement spreads every edge over three times as many pixels.
//!
//! The rendered sizes up to 4032x3024, side by side with OpenCV's detectors, are in
//! BENCHMARKS.md (`examples/chessboard_scales.rs`).

use camgeom::Error;
use camgeom::chessboard::{
    BoardSize, Chessboard, ChessboardDetector, DetectParams, pyramid_len, scratch_len,
};
use camgeom_host::images::GrayImage;

use super::calib_chessboard::opencv_views;

fn enlarge(img: &GrayImage, s: u32) -> GrayImage {
    let src =
        image::GrayImage::from_raw(img.width as u32, img.height as u32, img.data.clone()).unwrap();
    let big = image::imageops::resize(
        &src,
        src.width() * s,
        src.height() * s,
        image::imageops::FilterType::Triangle,
    );
    GrayImage {
        width: big.width() as usize,
        height: big.height() as usize,
        data: big.into_raw(),
    }
}

#[test]
fn enlarged_bundled_views_are_found_at_opencvs_corners() {
    let board = BoardSize::new(9, 6).unwrap();
    let params = DetectParams::default();
    let mut det = Box::new(ChessboardDetector::<1024>::new());
    for s in [2u32, 3] {
        let (mut any_found, mut one_found, mut dists) = (0, 0, Vec::new());
        for v in opencv_views() {
            let img = camgeom_host::images::load_gray(crate::common::chessboard(&format!(
                "{}.jpg",
                v.name
            )))
            .unwrap();
            let big = enlarge(&img, s);
            let view = big.view().unwrap();
            let mut scratch = vec![0i32; scratch_len(big.width)];
            let mut pyramid = vec![0u8; pyramid_len(big.width, big.height)];
            let one: Option<Chessboard<54>> =
                det.detect(&view, board, &params, &mut scratch).unwrap();
            one_found += usize::from(one.is_some());
            let found: Chessboard<54> = det
                .detect_any_scale(&view, board, &params, &mut pyramid, &mut scratch)
                .unwrap()
                .unwrap_or_else(|| panic!("{} at {s}x: not found ({:?})", v.name, det.seen()));
            any_found += 1;
            let sf = f64::from(s);
            for (p, q) in found.corners.iter().zip(&v.subpix5) {
                let (x, y) = (sf * (q.x + 0.5) - 0.5, sf * (q.y + 0.5) - 0.5);
                dists.push((f64::from(p.x) - x).hypot(f64::from(p.y) - y));
            }
        }
        dists.sort_by(f64::total_cmp);
        let (median, max) = (dists[dists.len() / 2], dists[dists.len() - 1]);
        println!(
            "{s}x: detect_any_scale {any_found} of 13, detect {one_found}; distance to OpenCV's \
             corners (enlarged) median {median:.3} px, max {max:.3} px"
        );
        assert_eq!(any_found, 13);
        // At 640x480 camgeom's corners are 0.2 px (median) from OpenCV's 5x5 cornerSubPix
        // ones, 0.6 px at most; enlarged, measured 0.20 / 0.81 px at 2x and 0.25 / 0.91 px at
        // 3x. A corner out of order or on the wrong saddle would be a square (tens of pixels)
        // away.
        assert!(median < 0.4, "median {median}");
        assert!(max < 1.5, "max {max}");
    }
}

#[test]
fn a_short_pyramid_buffer_is_an_error_and_a_blank_frame_is_no_board() {
    let board = BoardSize::new(9, 6).unwrap();
    let mut det = Box::new(ChessboardDetector::<64>::new());
    let img = GrayImage::filled(1920, 1080, 128);
    let view = img.view().unwrap();
    let mut scratch = vec![0i32; scratch_len(1920)];
    let mut short = vec![0u8; pyramid_len(1920, 1080) - 1];
    assert_eq!(
        det.detect_any_scale::<54>(
            &view,
            board,
            &DetectParams::default(),
            &mut short,
            &mut scratch
        ),
        Err(Error::BufferTooSmall("pyramid"))
    );
    let mut pyramid = vec![0u8; pyramid_len(1920, 1080)];
    let none = det
        .detect_any_scale::<54>(
            &view,
            board,
            &DetectParams::default(),
            &mut pyramid,
            &mut scratch,
        )
        .unwrap();
    assert!(none.is_none());
    assert_eq!(det.seen().x_corners, 0);
}
