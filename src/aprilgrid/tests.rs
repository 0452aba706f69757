//! The 2-cell-border family's decoding and the grid's layout and view corners.

extern crate std;

use std::boxed::Box;
use std::vec;
use std::vec::Vec;

use super::*;
use crate::Error;
use crate::apriltag::families::{TAG36H11, TAG36H11_B2};
use crate::apriltag::{Detection, Detector, DetectorConfig, Family};
use crate::image::ImageView;

type Small = crate::apriltag::Workspace320x240;

/// Draws tag `id` of `f` (its whole `total_width` square, `Family::cell`) turned `quarter`
/// quarter turns clockwise, the border's outer corner at pixel `(x0, y0)`, `cell` px a cell.
fn draw(
    px: &mut [u8],
    w: usize,
    f: &Family,
    id: u16,
    (x0, y0): (i32, i32),
    cell: i32,
    quarter: u8,
) {
    let wab = i32::from(f.width_at_border());
    let lo = (wab - i32::from(f.total_width())) / 2;
    for cy in lo..lo + i32::from(f.total_width()) {
        for cx in lo..lo + i32::from(f.total_width()) {
            let (mut sx, mut sy) = (cx, cy);
            for _ in 0..quarter {
                (sx, sy) = (sy, wab - 1 - sx);
            }
            let white = f.cell(id, sx, sy).unwrap();
            for dy in 0..cell {
                for dx in 0..cell {
                    let (u, v) = (x0 + cx * cell + dx, y0 + cy * cell + dy);
                    if u >= 0
                        && v >= 0
                        && (u as usize) < w
                        && (v as usize) * w + (u as usize) < px.len()
                    {
                        px[v as usize * w + u as usize] = if white { 235 } else { 25 };
                    }
                }
            }
        }
    }
}

fn detect(px: &[u8], w: usize, h: usize, fams: &[&'static Family]) -> heapless::Vec<Detection, 16> {
    let det = Detector::new(DetectorConfig::default(), fams).unwrap();
    let mut ws = Box::new(Small::new());
    det.detect(&ImageView::packed(px, w, h).unwrap(), &mut ws.as_mut_view())
        .unwrap()
}

#[test]
fn the_two_cell_border_family_is_tag36h11_moved_in_by_a_cell() {
    assert_eq!(
        (TAG36H11_B2.width_at_border(), TAG36H11_B2.total_width()),
        (10, 12)
    );
    assert_eq!(TAG36H11_B2.border_bits(), 2);
    assert_eq!(TAG36H11_B2.ncodes(), TAG36H11.ncodes());
    for id in [0u16, 1, 200, 586] {
        assert_eq!(TAG36H11_B2.code(id), TAG36H11.code(id));
        for y in -1..11 {
            for x in -1..11 {
                let want = if (0..10).contains(&x) && (0..10).contains(&y) {
                    let depth = x.min(y).min(9 - x).min(9 - y);
                    // The payload is tag36h11's, a cell further in; two black rings outside it.
                    if depth >= 2 {
                        TAG36H11.cell(id, x - 1, y - 1).unwrap()
                    } else {
                        false
                    }
                } else {
                    true
                };
                assert_eq!(TAG36H11_B2.cell(id, x, y), Some(want), "id {id} ({x}, {y})");
            }
        }
        assert_eq!(TAG36H11_B2.cell(id, -2, 0), None);
    }
}

#[test]
fn two_cell_border_tags_decode_in_every_orientation_with_their_outer_corners() {
    let (w, h) = (240, 160);
    for (id, quarter) in [(0u16, 0u8), (5, 1), (101, 2), (586, 3)] {
        let mut px = vec![128u8; w * h];
        let (cell, x0, y0) = (6, 60, 30);
        draw(&mut px, w, &TAG36H11_B2, id, (x0, y0), cell, quarter);
        let got = detect(&px, w, h, &[&TAG36H11_B2]);
        assert_eq!(got.len(), 1, "id {id} q{quarter}: {got:?}");
        assert_eq!((got[0].id, got[0].hamming), (id, 0));
        let s = 10.0 * cell as f32;
        let (l, t) = (x0 as f32 - 0.5, y0 as f32 - 0.5);
        let square = [(l, t + s), (l + s, t + s), (l + s, t), (l, t)];
        for (i, c) in got[0].corners.iter().enumerate() {
            let (ex, ey) = square[(i + 3 * usize::from(quarter)) % 4];
            assert!(
                (c.x - ex).abs() < 0.1 && (c.y - ey).abs() < 0.1,
                "{i}: {c:?}"
            );
        }
    }
}

#[test]
fn a_border_width_reads_only_its_own_tags() {
    let (w, h) = (240, 160);
    let mut mixed = 0;
    for id in 0..40u16 {
        for (drawn, other) in [(&TAG36H11_B2, &TAG36H11), (&TAG36H11, &TAG36H11_B2)] {
            let mut px = vec![128u8; w * h];
            draw(&mut px, w, drawn, id, (50, 30), 7, (id % 4) as u8);
            let wrong = detect(&px, w, h, &[other]);
            assert!(
                wrong.is_empty(),
                "{} id {id} read as {}: {wrong:?}",
                drawn.name(),
                other.name()
            );
            // With both families, the tag is found once, as its own.
            let both = detect(&px, w, h, &[&TAG36H11, &TAG36H11_B2]);
            assert_eq!(both.len(), 1, "{} id {id}: {both:?}", drawn.name());
            assert_eq!((both[0].family.name(), both[0].id), (drawn.name(), id));
            mixed += 1;
        }
    }
    assert_eq!(mixed, 80);
}

#[test]
fn the_layout_is_kalibrs() {
    let g = AprilGrid::new(3, 2, 0.05, 0.25).unwrap();
    assert_eq!((g.tags(), g.points()), (6, 24));
    // Kalibr's createGridPoints, point r * 2 cols + c.
    for k in 0..24 {
        let (r, c) = (k / 6, k % 6);
        let x = (c / 2) as f32 * 1.25 * 0.05 + (c % 2) as f32 * 0.05;
        let y = (r / 2) as f32 * 1.25 * 0.05 + (r % 2) as f32 * 0.05;
        let p = g.point(k).unwrap();
        assert!((p.x - x).abs() < 1e-7 && (p.y - y).abs() < 1e-7, "{k}");
    }
    assert_eq!(g.point(24), None);
    // computeObservation's pIdx for tag 4 (row 1, column 1): base 1 * 12 + 1 * 2 = 14.
    assert_eq!(g.tag_points(4), Some([14, 15, 21, 20]));
    assert_eq!(g.tag_points(6), None);
    // Every point is one tag's corner, once; the corners are the tag's square, counter-
    // clockwise from bottom-left in the y-up board frame.
    let mut used = [0u8; 24];
    for t in 0..6 {
        let ids = g.tag_points(t).unwrap();
        let p = ids.map(|k| g.point(k).unwrap());
        let (x0, y0) = ((t % 3) as f32 * 1.25 * 0.05, (t / 3) as f32 * 1.25 * 0.05);
        let want = [
            (x0, y0),
            (x0 + 0.05, y0),
            (x0 + 0.05, y0 + 0.05),
            (x0, y0 + 0.05),
        ];
        for (q, w) in p.iter().zip(want) {
            assert!((q.x - w.0).abs() < 1e-7 && (q.y - w.1).abs() < 1e-7);
        }
        ids.iter().for_each(|&k| used[k] += 1);
    }
    assert!(used.iter().all(|&u| u == 1));
}

#[test]
fn bad_grids_are_refused() {
    assert_eq!(
        AprilGrid::new(0, 3, 1.0, 0.3),
        Err(Error::InvalidParameter("tags"))
    );
    assert_eq!(
        AprilGrid::new(25, 24, 1.0, 0.3),
        Err(Error::InvalidParameter("tags"))
    );
    assert!(AprilGrid::new(587, 1, 1.0, 0.3).is_ok());
    assert_eq!(
        AprilGrid::new(2, 2, 0.0, 0.3),
        Err(Error::InvalidParameter("size"))
    );
    assert_eq!(
        AprilGrid::new(2, 2, f32::NAN, 0.3),
        Err(Error::InvalidParameter("size"))
    );
    assert_eq!(
        AprilGrid::new(2, 2, 1.0, 0.0),
        Err(Error::InvalidParameter("spacing"))
    );
    assert_eq!(
        AprilGrid::new(2, 2, 1.0, 1.5),
        Err(Error::InvalidParameter("spacing"))
    );
    assert_eq!(
        AprilGrid::new(2, 2, 1.0, f32::NAN),
        Err(Error::InvalidParameter("spacing"))
    );
    // The threshold fraction the grid's configuration sets, and ones a detector refuses.
    assert!(Detector::new(AprilGrid::detector_config(), &[&TAG36H11_B2]).is_ok());
    for f in [0.1, 0.9, f32::NAN] {
        let cfg = DetectorConfig {
            threshold_fraction: f,
            ..DetectorConfig::default()
        };
        assert_eq!(
            Detector::new(cfg, &[&TAG36H11_B2]).err(),
            Some(Error::InvalidParameter("threshold_fraction"))
        );
    }
}

/// A 3x2 grid drawn upright (tag 0 at the bottom-left), with Kalibr's corner squares: 6 px a
/// cell, gap 3 cells, and a seeded noise of ±3 grey levels (drawn exactly on the pixel grid,
/// a tag's boundary without the corner's diagonal point is symmetric about each corner, and
/// the quad fit's strict error maxima tie there; any real image breaks the tie). Returns the
/// frame and the pixel of every grid point.
fn grid_frame(g: &AprilGrid, w: usize, h: usize) -> (Vec<u8>, Vec<(f32, f32)>) {
    let mut px = vec![235u8; w * h];
    let (cell, gap) = (6i32, 18i32);
    let (ox, bottom) = (30i32, 170i32); // tag 0's outer bottom-left corner, pixel edges
    let mut truth = vec![(0.0, 0.0); g.points()];
    for t in 0..g.tags() {
        let (tx, ty) = ((t % g.cols()) as i32, (t / g.cols()) as i32);
        let x0 = ox + tx * (60 + gap);
        let y0 = bottom - 60 - ty * (60 + gap);
        draw(&mut px, w, &TAG36H11_B2, t as u16, (x0, y0), cell, 0);
        for (sx, sy) in [
            (x0 - gap, y0 - gap),
            (x0 + 60, y0 - gap),
            (x0 + 60, y0 + 60),
            (x0 - gap, y0 + 60),
        ] {
            for v in sy..sy + gap {
                for u in sx..sx + gap {
                    if u >= 0 && v >= 0 && (u as usize) < w && (v as usize) < h {
                        px[v as usize * w + u as usize] = 25;
                    }
                }
            }
        }
        let (l, tp) = (x0 as f32 - 0.5, y0 as f32 - 0.5);
        let corners = [
            (l, tp + 60.0),
            (l + 60.0, tp + 60.0),
            (l + 60.0, tp),
            (l, tp),
        ];
        for (k, c) in g.tag_points(t).unwrap().iter().zip(corners) {
            truth[*k] = c;
        }
    }
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    for p in px.iter_mut() {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        *p = (i32::from(*p) + (seed % 7) as i32 - 3) as u8;
    }
    (px, truth)
}

#[test]
fn a_grid_view_gives_every_corner_at_its_point() {
    let (w, h) = (280, 200);
    let g = AprilGrid::new(3, 2, 0.03, 0.3).unwrap();
    let (px, truth) = grid_frame(&g, w, h);
    let det = Detector::new(DetectorConfig::default(), &[&TAG36H11_B2]).unwrap();
    let mut ws = Box::new(Small::new());
    let frame = ImageView::packed(&px, w, h).unwrap();
    let mut tags: heapless::Vec<Detection, 16> = heapless::Vec::new();
    let mut out = [GridCorner::default(); 24];
    let n = g
        .detect_corners(
            &det,
            &frame,
            &mut ws.as_mut_view(),
            &mut tags,
            None,
            &mut out,
        )
        .unwrap();
    assert_eq!(n, 24, "{tags:?}");
    for (k, c) in out.iter().enumerate() {
        assert_eq!(usize::from(c.id), k);
        let (x, y) = truth[k];
        assert!(
            (c.point.x - x).abs() < 0.15 && (c.point.y - y).abs() < 0.15,
            "{k}: {c:?} vs {:?}",
            truth[k]
        );
    }
    // A detector without the family, a short buffer: named errors.
    let other = Detector::new(DetectorConfig::default(), &[&TAG36H11]).unwrap();
    assert_eq!(
        g.detect_corners(
            &other,
            &frame,
            &mut ws.as_mut_view(),
            &mut tags,
            None,
            &mut out
        ),
        Err(Error::InvalidParameter("detector"))
    );
    assert_eq!(
        g.detect_corners(
            &det,
            &frame,
            &mut ws.as_mut_view(),
            &mut tags,
            None,
            &mut out[..23]
        ),
        Err(Error::BufferTooSmall("corners"))
    );
}

/// Kalibr's refinement: every tag corner is a crossing with a corner square, refined there as a
/// saddle point; a grid without the squares has no saddle and its corners are dropped.
#[test]
fn corners_refine_as_saddles_at_the_corner_squares() {
    let (w, h) = (280, 200);
    let g = AprilGrid::new(3, 2, 0.03, 0.3).unwrap();
    let (px, truth) = grid_frame(&g, w, h);
    let det = Detector::new(AprilGrid::detector_config(), &[&TAG36H11_B2]).unwrap();
    let mut ws = Box::new(Small::new());
    let frame = ImageView::packed(&px, w, h).unwrap();
    let mut tags: heapless::Vec<Detection, 16> = heapless::Vec::new();
    let mut out = [GridCorner::default(); 24];
    let saddle = crate::chessboard::SaddleConfig::default().check().unwrap();
    let n = g
        .detect_corners(
            &det,
            &frame,
            &mut ws.as_mut_view(),
            &mut tags,
            Some(&saddle),
            &mut out,
        )
        .unwrap();
    assert_eq!(n, 24);
    for c in &out {
        let (x, y) = truth[usize::from(c.id)];
        assert!(
            (c.point.x - x).abs() < 0.1 && (c.point.y - y).abs() < 0.1,
            "{c:?}"
        );
    }
    // Not a crossing: a corner in a flat white area does not move and is dropped; a
    // non-finite one is dropped; n past the slice is bounded.
    let mut flat = [
        GridCorner {
            id: 3,
            point: nalgebra::Point2::new(5.0, 5.0),
        },
        GridCorner {
            id: 4,
            point: nalgebra::Point2::new(f32::NAN, 1.0),
        },
    ];
    assert_eq!(refine_corners(&frame, &mut flat, 9, &saddle), Ok(0));
}

#[test]
fn ids_seen_twice_or_off_the_grid_or_of_another_family_are_not_used() {
    let (w, h) = (280, 200);
    let g = AprilGrid::new(3, 2, 0.03, 0.3).unwrap();
    let (px, _) = grid_frame(&g, w, h);
    let all = detect(&px, w, h, &[&TAG36H11_B2]);
    assert_eq!(all.len(), 6);
    let mut out = [GridCorner::default(); 24];
    // A second tag 2 elsewhere: both copies go (4 corners fewer).
    let mut dets: Vec<Detection> = all.iter().copied().collect();
    let mut copy = dets[2];
    copy.corners.iter_mut().for_each(|p| p.x += 100.0);
    dets.push(copy);
    assert_eq!(grid_corners(&g, &dets, &mut out), Ok(20));
    assert!(
        out[..20]
            .iter()
            .all(|c| !g.tag_points(2).unwrap().contains(&usize::from(c.id)))
    );
    // An id past the grid, a tag of another family: ignored.
    let mut dets: Vec<Detection> = all.iter().copied().collect();
    dets[0].id = 6;
    dets[1].family = &TAG36H11;
    assert_eq!(grid_corners(&g, &dets, &mut out), Ok(16));
    assert_eq!(
        grid_corners(&g, &dets, &mut out[..10]),
        Err(Error::BufferTooSmall("corners"))
    );
    assert_eq!(grid_corners(&g, &[], &mut out), Ok(0));
}
