//! Unit tests of the detector: the code tables and decoder, the run-length scans against a
//! per-pixel transcription of AprilTag's loops, detection of drawn tags, the pose, bad input.

use std::vec;
use std::vec::Vec;

use nalgebra::{Point2, Point3, Vector3};
use proptest::prelude::*;

use super::families::{
    ALL, ARUCO, DICT_4X4_50, DICT_4X4_1000, DICT_6X6_250, DICT_ARUCO_ORIGINAL, TAG_STANDARD41H12,
    TAG16H5, TAG25H9, TAG36H11,
};
use super::segment::{
    BLACK, MIN_COMPONENT, Rows, Run, SKIP, Sampled, Sink, WHITE, boundary_scan,
    boundary_scan_cached, build_tiles, label_pass, row_runs, tile_count,
};
use super::*;
use crate::camera::{Camera, Intrinsics};
use crate::image::ImageView;
use crate::pose::PlanarConfig;
use crate::transform::Pose;

// ---------------------------------------------------------------- families and decoding

/// Brute force: the first code (in id order) within `maxh` bits of `r` in some rotation.
fn brute_decode(f: &Family, r: u64, maxh: u32) -> Option<(u16, u32)> {
    let mut best: Option<(u16, u32)> = None;
    let mut w = r;
    for _ in 0..4 {
        for (id, c) in (0..f.ncodes()).filter_map(|i| Some((i, f.codes.get(i)?))) {
            let h = (c ^ w).count_ones();
            if h <= maxh && best.is_none_or(|b| h < b.1) {
                best = Some((id as u16, h));
            }
        }
        w = rotate90(w, f.nbits());
    }
    best
}

#[test]
fn tag36h11_id_0_is_apriltags_code() {
    // AprilTag's tag36h11.c, codedata[0].
    assert_eq!(TAG36H11.code(0), Some(0xd7e00984b));
    assert_eq!(TAG36H11.ncodes(), 587);
    assert_eq!(TAG25H9.ncodes(), 35);
    assert_eq!(TAG16H5.ncodes(), 30);
    assert_eq!(TAG_STANDARD41H12.ncodes(), 2115);
}

#[test]
fn rotate90_is_a_quarter_turn_of_the_cells() {
    for f in ALL {
        let n = f.nbits();
        for id in [0u16, 1, 7, (f.ncodes() - 1) as u16] {
            let c = f.code(id).unwrap();
            let r = rotate90(c, n);
            assert_eq!(rotate90(rotate90(rotate90(r, n), n), n), c, "{}", f.name());
            // The rotated word's cell (x, y) is the original's cell turned about the border's
            // centre (AprilTag's rotate90 turns the image clockwise, y down).
            let wab = i32::from(f.width_at_border());
            for (i, b) in f.layout().iter().enumerate() {
                let bit = |w: u64, k: usize| (w >> (n as usize - 1 - k)) & 1;
                let (x, y) = (i32::from(b.x), i32::from(b.y));
                // The cell moves (x, y) -> (y, wab - 1 - x): a quarter turn counter-clockwise
                // on screen (y down).
                let (xr, yr) = (y, wab - 1 - x);
                let j = f
                    .layout()
                    .iter()
                    .position(|q| i32::from(q.x) == xr && i32::from(q.y) == yr)
                    .unwrap();
                assert_eq!(bit(c, i), bit(r, j), "{} id {id} bit {i}", f.name());
            }
        }
    }
}

#[test]
fn every_id_and_rotation_decodes_exactly_and_with_one_bit_wrong() {
    for f in ALL {
        let n = f.nbits();
        for id in 0..f.ncodes() as u16 {
            let c = f.code(id).unwrap();
            let mut w = c;
            for k in 0..4u8 {
                // w = rotate90^k(code): the decoder turns it back by (4 - k) quarters.
                let want = (4 - k) % 4;
                let d = f.decode(w, 2).unwrap();
                assert_eq!((d.id, d.hamming, d.rotation), (id, 0, want), "{}", f.name());
                for bit in 0..n {
                    let d = f.decode(w ^ (1 << bit), 2).unwrap();
                    assert_eq!((d.id, d.hamming, d.rotation), (id, 1, want));
                }
                w = rotate90(w, n);
            }
        }
    }
}

/// Every code of every ArUco dictionary in every rotation decodes to the smallest id with a
/// code equal to it in some rotation (its own but for DICT_ARUCO_ORIGINAL's rotated
/// duplicates), with `max_correctable` wrong bits to what a search of every code gives, and a
/// prefix dictionary never answers an id past its own.
#[test]
fn aruco_dictionaries_decode_as_a_search_of_every_code() {
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    for f in ARUCO {
        let n = f.nbits();
        let e = f.max_correctable();
        assert!(e >= 1 || f.name() == "DICT_4X4_1000", "{}", f.name());
        let step = (f.ncodes() / 60).max(1);
        for id in (0..f.ncodes() as u16).step_by(step) {
            let mut w = f.code(id).unwrap();
            for _ in 0..4 {
                let d = f.decode(w, 0).unwrap();
                let want = brute_decode(f, w, 0).unwrap();
                assert_eq!((d.id, u32::from(d.hamming)), want, "{} id {id}", f.name());
                assert!(d.id <= id);
                // e wrong bits: the lookup finds what the search finds (the smallest id).
                let mut flipped = w;
                for _ in 0..e {
                    flipped ^= 1 << (next() % u64::from(n));
                }
                let got = f.decode(flipped, e).map(|d| d.id);
                let want = brute_decode_smallest(f, flipped, u32::from(e));
                assert_eq!(got, want, "{} id {id} {e} bits", f.name());
                w = rotate90(w, n);
            }
        }
        for _ in 0..200 {
            let w = next() & ((1u64 << n) - 1);
            let got = f.decode(w, e).map(|d| d.id);
            assert_eq!(
                got,
                brute_decode_smallest(f, w, u32::from(e)),
                "{}",
                f.name()
            );
            assert!(got.is_none_or(|id| usize::from(id) < f.ncodes()));
        }
    }
    // The shared table: DICT_4X4_50's codes are DICT_4X4_1000's first 50.
    for id in 0..50 {
        assert_eq!(DICT_4X4_50.code(id), DICT_4X4_1000.code(id));
    }
    assert_eq!(DICT_4X4_50.code(50), None);
}

/// The smallest id within `maxh` bits of `r` in some rotation (OpenCV's `identify`).
fn brute_decode_smallest(f: &Family, r: u64, maxh: u32) -> Option<u16> {
    let mut w = r;
    let mut best: Option<u16> = None;
    for _ in 0..4 {
        for id in 0..f.ncodes() as u16 {
            if (f.code(id).unwrap() ^ w).count_ones() <= maxh && best.is_none_or(|b| id < b) {
                best = Some(id);
            }
        }
        w = rotate90(w, f.nbits());
    }
    best
}

/// ArUco markers drawn from their cells in every orientation: found with their ids, OpenCV's
/// corner order turning with the marker (corner 0 is the marker's own top-left), a marker
/// drawn on black (no quiet zone) is not found, and DICT_ARUCO_ORIGINAL's marker 1023, its
/// own half turn, is found either way up.
#[test]
fn aruco_markers_are_found_in_every_orientation_with_opencvs_corner_order() {
    let (w, h) = (160, 120);
    for (f, id) in [
        (&DICT_4X4_50, 7u16),
        (&DICT_6X6_250, 201),
        (&DICT_ARUCO_ORIGINAL, 1023),
    ] {
        for quarter in 0..4u8 {
            let mut px = vec![128u8; w * h];
            let cell = 6;
            let (x0, y0) = (40, 20);
            draw(&mut px, w, f, id, (x0, y0), cell, quarter);
            let got = detect_all(&px, w, h, &[f]);
            assert_eq!(got.len(), 1, "{} q{quarter}: {got:?}", f.name());
            let d = &got[0];
            assert_eq!((d.id, d.hamming), (id, 0));
            let s = f32::from(f.width_at_border()) * cell as f32;
            let (l, t) = (x0 as f32 - 0.5, y0 as f32 - 0.5);
            // The upright marker's top-left, top-right, bottom-right, bottom-left; turned by
            // q quarters clockwise, corner i sits at the square's corner (i + q) mod 4.
            let square = [(l, t), (l + s, t), (l + s, t + s), (l, t + s)];
            let sym = if id == 1023 { 2 } else { 4 };
            let ok = (0..4).step_by(sym).any(|extra| {
                d.aruco_corners().iter().enumerate().all(|(i, c)| {
                    let (ex, ey) = square[(i + usize::from(quarter) + extra) % 4];
                    (c.x - ex).abs() < 0.1 && (c.y - ey).abs() < 0.1
                })
            });
            assert!(ok, "{} q{quarter}: {:?}", f.name(), d.aruco_corners());
        }
    }
    // No quiet zone: the same marker on black.
    let mut px = vec![25u8; w * h];
    draw(&mut px, w, &DICT_4X4_50, 7, (40, 20), 6, 0);
    for y in 0..h {
        for x in 0..w {
            let inside = (40..40 + 36).contains(&x) && (20..20 + 36).contains(&y);
            if !inside {
                px[y * w + x] = 25;
            }
        }
    }
    assert!(detect_all(&px, w, h, &[&DICT_4X4_50]).is_empty());
}

/// tag16h5 has distance 5: three wrong bits can land within two of another code. Measured
/// here so the docs' warning stays true: some 3-bit errors decode to a wrong id.
#[test]
fn tag16h5_three_bit_errors_can_decode_to_another_id() {
    let f = &TAG16H5;
    let c = f.code(0).unwrap();
    let mut wrong = 0;
    for a in 0..16 {
        for b in a + 1..16 {
            for e in b + 1..16 {
                if let Some(d) = f.decode(c ^ (1 << a) ^ (1 << b) ^ (1 << e), 2) {
                    assert_ne!(d.id, 0, "3 errors cannot be within 2 of the code itself");
                    wrong += 1;
                }
            }
        }
    }
    assert!(wrong > 0);
}

fn family_strategy() -> impl Strategy<Value = &'static Family> {
    prop::sample::select(ALL.to_vec())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// 0, 1 and 2 wrong bits decode to the id and rotation; 3 and more are rejected
    /// (tag36h11, tag25h9, tagStandard41h12: `min_distance - 3 > 2`).
    #[test]
    fn flipped_bits_decode_or_are_rejected(
        f in family_strategy(),
        id_frac in 0.0f64..1.0,
        k in 0u8..4,
        flips in prop::collection::btree_set(0u32..41, 0..6),
    ) {
        let n = f.nbits();
        let id = ((id_frac * f.ncodes() as f64) as u16).min(f.ncodes() as u16 - 1);
        let mut w = f.code(id).unwrap();
        for _ in 0..k {
            w = rotate90(w, n);
        }
        let flips: Vec<u32> = flips.into_iter().filter(|&b| b < n).collect();
        for &b in &flips {
            w ^= 1 << b;
        }
        let d = f.decode(w, 2);
        if flips.len() <= 2 {
            let d = d.unwrap();
            prop_assert_eq!((d.id, u32::from(d.hamming), d.rotation), (id, flips.len() as u32, (4 - k) % 4));
        } else if f.min_distance() as usize - flips.len() > 2 {
            prop_assert!(d.is_none(), "{} flips decoded: {:?}", flips.len(), d);
        }
    }

    /// The chunk-indexed lookup finds what a search of every code finds (3 bits corrected).
    #[test]
    fn chunk_lookup_matches_brute_force(f in family_strategy(), r in any::<u64>(), near in any::<bool>(), id_frac in 0.0f64..1.0, flips in prop::collection::vec(0u32..41, 0..4)) {
        let n = f.nbits();
        let mask = (1u64 << n) - 1;
        let w = if near {
            let id = ((id_frac * f.ncodes() as f64) as usize).min(f.ncodes() - 1);
            flips.iter().fold(f.codes.get(id).unwrap(), |w, &b| if b < n { w ^ (1 << b) } else { w })
        } else {
            r & mask
        };
        let got = f.decode(w, 3).map(|d| (d.id, u32::from(d.hamming)));
        let want = brute_decode(f, w, 3);
        // With 3 bits some families' correction is not unique: the lookup may return any
        // code within 3 bits, so compare presence and, when unique, the id.
        prop_assert_eq!(got.is_some(), want.is_some());
        if let (Some(g), Some(b)) = (got, want) && 2 * 3 < u32::from(f.min_distance()) {
            prop_assert_eq!(g.0, b.0);
        }
    }
}

// ------------------------------------------------------------------ drawing test frames

/// A frame of `w x h` filled with `bg`, with tag `id` of `f` drawn axis-aligned at `cell`
/// pixels a cell, its border's outer corner at pixel `(x0, y0)`, turned by `quarter` clockwise
/// quarter turns (the family's own cells: `Family::cell`).
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
    let hi = lo + i32::from(f.total_width());
    for cy in lo..hi {
        for cx in lo..hi {
            // The cell shown at (cx, cy) after turning the tag `quarter` times clockwise.
            let (mut sx, mut sy) = (cx, cy);
            for _ in 0..quarter {
                // Inverse of (x, y) -> (wab - 1 - y, x).
                (sx, sy) = (sy, wab - 1 - sx);
            }
            let white = f.cell(id, sx, sy).unwrap();
            for dy in 0..cell {
                for dx in 0..cell {
                    let (u, v) = (x0 + cx * cell + dx, y0 + cy * cell + dy);
                    if u >= 0
                        && v >= 0
                        && (u as usize) < w
                        && ((v as usize) * w + u as usize) < px.len()
                    {
                        px[v as usize * w + u as usize] = if white { 235 } else { 25 };
                    }
                }
            }
        }
    }
}

type Small = Workspace<160, { tiles_len(160, 120, 1) }, 4096, 256, 4096, { sort_len(160, 120, 1) }>;

/// The tags of `fams` in a packed `w x h` frame, with the default configuration.
fn detect_all(
    px: &[u8],
    w: usize,
    h: usize,
    fams: &[&'static Family],
) -> heapless::Vec<Detection, 8> {
    detect_with(DetectorConfig::default(), px, w, h, fams)
}

/// The tags of `fams` in a packed `w x h` frame, with `cfg` and a [`Small`] workspace.
fn detect_with<const N: usize>(
    cfg: DetectorConfig,
    px: &[u8],
    w: usize,
    h: usize,
    fams: &[&'static Family],
) -> heapless::Vec<Detection, N> {
    let det = Detector::new(cfg, fams).unwrap();
    let mut ws = std::boxed::Box::new(Small::new());
    det.detect(&ImageView::packed(px, w, h).unwrap(), &mut ws.as_mut_view())
        .unwrap()
}

#[test]
fn each_family_detects_its_drawn_tags_in_every_orientation() {
    let (w, h) = (160, 120);
    for f in ALL {
        for (id, quarter) in [(0u16, 0u8), (3, 1), (17, 2), (29, 3)] {
            let mut px = vec![128u8; w * h];
            let cell = 6;
            let (x0, y0) = (40, 20);
            draw(&mut px, w, f, id, (x0, y0), cell, quarter);
            let got = detect_all(&px, w, h, &[f]);
            assert_eq!(got.len(), 1, "{} id {id} q{quarter}: {got:?}", f.name());
            let d = &got[0];
            assert_eq!((d.id, d.hamming), (id, 0), "{}", f.name());
            // The border's outer square: pixels x0 .. x0 + wab cell, edges half a pixel out.
            let s = f32::from(f.width_at_border()) * cell as f32;
            let (l, t) = (x0 as f32 - 0.5, y0 as f32 - 0.5);
            let square = [(l, t + s), (l + s, t + s), (l + s, t), (l, t)];
            // Corner i of AprilTag's order is tag coordinate CORNER_TAG_COORDS[i]; turned by q
            // quarters clockwise on screen it sits where corner (i + q) mod 4 of the upright
            // square is (bottom-left, bottom-right, top-right, top-left turn clockwise).
            for (i, c) in d.corners.iter().enumerate() {
                let (ex, ey) = square[(i + 3 * usize::from(quarter)) % 4];
                // Sharp synthetic edges: the refined corners land on the pixel edges within
                // a few hundredths; 0.1 px leaves room for the f32 line fits.
                assert!(
                    (c.x - ex).abs() < 0.1 && (c.y - ey).abs() < 0.1,
                    "{} id {id} q{quarter} corner {i}: {c:?} vs ({ex}, {ey})",
                    f.name()
                );
            }
            let centre = Point2::new(l + s / 2.0, t + s / 2.0);
            assert!((d.center - centre).norm() < 0.1);
            // H maps tag coordinates to the corners.
            for (c, &(x, y)) in d.corners.iter().zip(CORNER_TAG_COORDS.iter()) {
                let p = d.homography.transfer(&Point2::new(x, y)).unwrap();
                assert!((p - c).norm() < 1e-3);
            }
        }
    }
}

#[test]
fn two_tags_are_both_found_sorted_by_id_and_the_target_corners_follow_the_target_order() {
    let (w, h) = (160, 120);
    let mut px = vec![140u8; w * h];
    draw(&mut px, w, &TAG36H11, 200, (10, 20), 5, 0);
    draw(&mut px, w, &TAG36H11, 5, (90, 40), 6, 1);
    let got = detect_all(&px, w, h, &[&TAG36H11]);
    assert_eq!(got.iter().map(|d| d.id).collect::<Vec<_>>(), [5, 200]);
    let det = Detector::new(DetectorConfig::default(), &[&TAG36H11]).unwrap();
    let mut ws = std::boxed::Box::new(Small::new());
    let frame = ImageView::packed(&px, w, h).unwrap();
    let t = det
        .find_target(&frame, &mut ws.as_mut_view(), &TAG36H11, 200)
        .unwrap()
        .unwrap();
    // Target (0, 0), (w, 0), (w, h), (0, h): the upright tag's top-left, top-right,
    // bottom-right, bottom-left.
    let s = 40.0;
    let want = [
        (9.5, 19.5),
        (9.5 + s, 19.5),
        (9.5 + s, 19.5 + s),
        (9.5, 19.5 + s),
    ];
    for (p, (x, y)) in t.iter().zip(want) {
        assert!((p.x - x).abs() < 0.1 && (p.y - y).abs() < 0.1, "{t:?}");
    }
    assert_eq!(
        det.find_target(&frame, &mut ws.as_mut_view(), &TAG36H11, 201)
            .unwrap(),
        None
    );
    assert_eq!(
        det.find_target(&frame, &mut ws.as_mut_view(), &TAG25H9, 5)
            .unwrap(),
        None
    );
}

/// A view of buffers sized at run time (a host's `Vec`s) detects as the owner does.
#[test]
fn a_view_of_run_time_buffers_detects_as_a_workspace_does() {
    let (w, h) = (160, 120);
    let mut px = vec![140u8; w * h];
    draw(&mut px, w, &TAG36H11, 200, (10, 20), 5, 0);
    draw(&mut px, w, &TAG36H11, 5, (90, 40), 6, 1);
    let frame = ImageView::packed(&px, w, h).unwrap();
    let det = Detector::new(DetectorConfig::default(), &[&TAG36H11]).unwrap();
    let mut ws = std::boxed::Box::new(Small::new());
    let want: heapless::Vec<Detection, 8> = det.detect(&frame, &mut ws.as_mut_view()).unwrap();
    let (labels, clusters, points) = (4096, 256, 4096);
    let (mut tiles, mut ring_min, mut ring_max) =
        (vec![0; tiles_len(w, h, 1)], vec![0; w], vec![0; w]);
    let (mut run0, mut run1) = (vec![Run::EMPTY; w], vec![Run::EMPTY; w]);
    let (mut parent, mut size) = (vec![0; labels], vec![0; labels]);
    let mut slots = vec![quad::Cluster::EMPTY; clusters];
    let (mut pts, mut keys) = (vec![0; points], vec![0; sort_len(w, h, 1)]);
    let mut stats = Stats::default();
    let mut view = WorkspaceView::new(
        &mut tiles,
        &mut ring_min,
        &mut ring_max,
        [&mut run0, &mut run1],
        &mut parent,
        &mut size,
        &mut slots,
        &mut pts,
        &mut keys,
        &mut stats,
    );
    let got: heapless::Vec<Detection, 8> = det.detect(&frame, &mut view).unwrap();
    assert_eq!(got, want);
    assert_eq!(view.stats(), ws.stats());
    assert_eq!(got.len(), 2);
}

#[test]
fn a_tag_cut_by_the_frame_edge_is_dropped_unless_asked_for() {
    let (w, h) = (160, 120);
    let mut px = vec![140u8; w * h];
    // The quiet zone's right column is outside the frame.
    draw(&mut px, w, &TAG36H11, 9, (160 - 42, 30), 5, 0);
    assert!(detect_all(&px, w, h, &[&TAG36H11]).is_empty());
    let cfg = DetectorConfig {
        reject_clipped: false,
        ..DetectorConfig::default()
    };
    let got: heapless::Vec<Detection, 4> = detect_with(cfg, &px, w, h, &[&TAG36H11]);
    assert_eq!(got.iter().map(|d| d.id).collect::<Vec<_>>(), [9]);
}

#[test]
fn decimation_finds_large_tags_with_refined_corners() {
    let (w, h) = (320, 240);
    let mut px = vec![120u8; w * h];
    draw(&mut px, w, &TAG36H11, 77, (60, 40), 12, 0);
    let cfg = DetectorConfig {
        decimate: 2,
        ..DetectorConfig::default()
    };
    let det = Detector::new(cfg, &[&TAG36H11]).unwrap();
    let mut ws = std::boxed::Box::new(Small::new());
    let frame = ImageView::packed(&px, w, h).unwrap();
    let got: heapless::Vec<Detection, 4> = det.detect(&frame, &mut ws.as_mut_view()).unwrap();
    assert_eq!(got.len(), 1);
    // Edge refinement at full resolution undoes the decimated fit's error (AprilTag's purpose
    // for it): within 0.1 px again.
    let tl = got[0].corners[3];
    assert!(
        (tl.x - 59.5).abs() < 0.1 && (tl.y - 39.5).abs() < 0.1,
        "{tl:?}"
    );
    assert_eq!(ws.stats().width, 160);
}

#[test]
fn overlapping_duplicates_keep_the_better_one() {
    let (w, h) = (160, 120);
    let mut px = vec![140u8; w * h];
    draw(&mut px, w, &TAG36H11, 42, (40, 30), 6, 0);
    let got: heapless::Vec<Detection, 4> =
        detect_with(DetectorConfig::default(), &px, w, h, &[&TAG36H11]);
    let mut a = got[0];
    let mut b = a;
    b.hamming = 1;
    b.corners.iter_mut().for_each(|c| c.x += 2.0);
    let mut stats = Stats::default();
    let mut out: heapless::Vec<Detection, 4> = heapless::Vec::new();
    detector::merge_for_tests(&mut out, b, &mut stats);
    detector::merge_for_tests(&mut out, a, &mut stats);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].hamming, 0);
    assert_eq!(stats.duplicates, 1);
    // Apart, both stay.
    a.corners.iter_mut().for_each(|c| c.x += 100.0);
    detector::merge_for_tests(&mut out, a, &mut stats);
    assert_eq!(out.len(), 2);
}

// --------------------------------------------------------- the scans against AprilTag's loops

/// Collects the points of a scan.
struct Collect(Vec<ScanPoint>);

impl Sink for Collect {
    fn run(
        &mut self,
        _: &mut [u32],
        key: u32,
        x2: usize,
        y2: usize,
        count: usize,
        gx: i32,
        gy: i32,
    ) {
        for i in 0..count {
            self.0.push((key, (x2 + 2 * i) as i32, y2 as i32, gx, gy));
        }
    }
}

/// The classes of `px` as the detector sees them (from its runs).
fn classes(src: &Sampled<'_>, tiles: &segment::Tiles<'_>) -> Vec<u8> {
    let mut out = vec![SKIP; src.w * src.h];
    let mut runs = vec![Run::EMPTY; src.w];
    for y in 0..src.h {
        let n = row_runs(src, tiles, y, &mut runs);
        for r in &runs[..n] {
            for x in r.x0..r.x1 {
                out[y * src.w + usize::from(x)] = r.c;
            }
        }
    }
    out
}

/// Components of a class image by flood fill (white 8-connected, black 4-connected): per
/// pixel the smallest pixel index of its component, and the component sizes.
fn components(cls: &[u8], w: usize, h: usize) -> (Vec<usize>, Vec<usize>) {
    let mut comp = vec![usize::MAX; w * h];
    let mut size = vec![0usize; w * h];
    for start in 0..w * h {
        if cls[start] == SKIP || comp[start] != usize::MAX {
            continue;
        }
        let c = cls[start];
        let mut stack = vec![start];
        comp[start] = start;
        let mut members = 0;
        while let Some(p) = stack.pop() {
            members += 1;
            let (x, y) = ((p % w) as i32, (p / w) as i32);
            for (dx, dy) in [
                (-1, 0),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (1, -1),
                (-1, 1),
                (1, 1),
            ] {
                if c == BLACK && dx != 0 && dy != 0 {
                    continue;
                }
                let (u, v) = (x + dx, y + dy);
                if u < 0 || v < 0 || u >= w as i32 || v >= h as i32 {
                    continue;
                }
                let q = v as usize * w + u as usize;
                if cls[q] == c && comp[q] == usize::MAX {
                    comp[q] = start;
                    stack.push(q);
                }
            }
        }
        size[start] = members;
    }
    (comp, size)
}

/// AprilTag's `do_gradient_clusters` loops, transcribed per pixel: `(black comp, white comp,
/// x2, y2, gx, gy)` for every point.
fn reference_points(cls: &[u8], w: usize, h: usize) -> Vec<(usize, usize, i32, i32, i32, i32)> {
    let (comp, size) = components(cls, w, h);
    let big = |p: usize| cls[p] != SKIP && size[comp[p]] >= usize::from(MIN_COMPONENT);
    let mut out = Vec::new();
    for y in 1..h.saturating_sub(1) {
        let mut connected_last = false;
        for x in 1..w - 1 {
            let p = y * w + x;
            if !big(p) {
                connected_last = false;
                continue;
            }
            let conn = |dx: i32, dy: i32, out: &mut Vec<_>| -> bool {
                let q = (y as i32 + dy) as usize * w + (x as i32 + dx) as usize;
                if cls[q] == SKIP || cls[q] == cls[p] || !big(q) {
                    return false;
                }
                let s = if cls[q] == WHITE { 1 } else { -1 };
                let (b, wc) = if cls[p] == BLACK {
                    (comp[p], comp[q])
                } else {
                    (comp[q], comp[p])
                };
                out.push((b, wc, 2 * x as i32 + dx, 2 * y as i32 + dy, dx * s, dy * s));
                true
            };
            conn(1, 0, &mut out);
            conn(0, 1, &mut out);
            if !connected_last {
                conn(-1, 1, &mut out);
            }
            connected_last = conn(1, 1, &mut out);
        }
    }
    out
}

/// A scan's point: `(key, x2, y2, gx, gy)`.
type ScanPoint = (u32, i32, i32, i32, i32);

fn scan_points(px: &[u8], w: usize, h: usize) -> (Vec<u8>, Vec<ScanPoint>) {
    let img = ImageView::packed(px, w, h).unwrap();
    let src = Sampled::new(img, 1);
    let mut thr = vec![0u8; tile_count(w, h)];
    let (mut rmin, mut rmax) = (vec![0u8; w], vec![0u8; w]);
    let tiles = build_tiles(&src, 5, 128, &mut thr, &mut rmin, &mut rmax);
    let cls = classes(&src, &tiles);
    let (mut r0, mut r1) = (vec![Run::EMPTY; w], vec![Run::EMPTY; w]);
    let mut rows = Rows {
        runs: [&mut r0, &mut r1],
    };
    let (mut parent, mut size) = (vec![0u16; w * h], vec![0u8; w * h]);
    let lab = label_pass(&src, &tiles, &mut rows, &mut parent, &mut size, &mut []);
    assert_eq!(lab.exhausted, 0);
    let mut sink = Collect(Vec::new());
    boundary_scan(
        &src,
        &tiles,
        &mut rows,
        &parent,
        &size,
        lab.labels,
        &mut [],
        &mut sink,
    );
    (cls, sink.0)
}

/// The points of a scan from the run cache (in a buffer of `words`; `None` when the runs do
/// not fit), upper rows `ylo..=yhi`.
fn cached_points(
    px: &[u8],
    w: usize,
    h: usize,
    words: usize,
    (ylo, yhi): (usize, usize),
) -> Option<Vec<ScanPoint>> {
    let img = ImageView::packed(px, w, h).unwrap();
    let src = Sampled::new(img, 1);
    let mut thr = vec![0u8; tile_count(w, h)];
    let (mut rmin, mut rmax) = (vec![0u8; w], vec![0u8; w]);
    let tiles = build_tiles(&src, 5, 128, &mut thr, &mut rmin, &mut rmax);
    let (mut r0, mut r1) = (vec![Run::EMPTY; w], vec![Run::EMPTY; w]);
    let mut rows = Rows {
        runs: [&mut r0, &mut r1],
    };
    let (mut parent, mut size) = (vec![0u16; w * h], vec![0u8; w * h]);
    let mut cache = vec![0u32; words];
    let lab = label_pass(&src, &tiles, &mut rows, &mut parent, &mut size, &mut cache);
    let mut sink = Collect(Vec::new());
    let at = lab.cached?;
    boundary_scan_cached::<_, false>(
        &mut cache,
        at,
        (w, h),
        (ylo, yhi),
        &mut rows,
        &parent,
        &size,
        &mut sink,
    );
    Some(sink.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The run-length scan gives AprilTag's points, each in the cluster of its two pixels'
    /// components, over random blocky images (every kind of run adjacency, noise on top).
    #[test]
    fn run_scan_gives_apriltags_boundary_points(
        seed in any::<u64>(),
        w in 12usize..48,
        h in 12usize..40,
        block in 1usize..6,
    ) {
        let mut g = crate::rng::Pcg32::new(seed);
        let (bw, bh) = (w.div_ceil(block), h.div_ceil(block));
        let blocks: Vec<u8> = (0..bw * bh).map(|_| if g.next_u32().is_multiple_of(2) { 30 } else { 220 }).collect();
        let px: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let v = blocks[(y / block) * bw + x / block];
                // Flat stretches (skipped tiles) and noise at block edges.
                if g.next_u32().is_multiple_of(7) { v ^ 0x3f } else { v }
            })
            .collect();
        let (cls, got) = scan_points(&px, w, h);
        let want = reference_points(&cls, w, h);
        // The scan from the run cache gives the same points in the same order; over rows
        // `ylo..=yhi`, those whose upper pixel is there; and no cache when the runs do not
        // fit (one word a row and one a run).
        prop_assert_eq!(cached_points(&px, w, h, w * h + h, (0, h)), Some(got.clone()));
        let (ylo, yhi) = (h / 3, h / 2);
        let part: Vec<_> = got
            .iter()
            .copied()
            .filter(|p| (ylo..=yhi).contains(&(p.2 as usize / 2)))
            .collect();
        prop_assert_eq!(cached_points(&px, w, h, w * h + h, (ylo, yhi)), Some(part));
        prop_assert_eq!(cached_points(&px, w, h, 2 * h - 1, (0, h)), None);
        // Same points (as a multiset), and one component pair per key.
        let mut a: Vec<_> = got.iter().map(|&(_, x, y, gx, gy)| (x, y, gx, gy)).collect();
        let mut b: Vec<_> = want.iter().map(|&(_, _, x, y, gx, gy)| (x, y, gx, gy)).collect();
        a.sort_unstable();
        b.sort_unstable();
        prop_assert_eq!(a, b);
        let mut key_of = std::collections::BTreeMap::new();
        let mut pair_of = std::collections::BTreeMap::new();
        let mut want_sorted = want.clone();
        let mut got_sorted = got.clone();
        want_sorted.sort_unstable_by_key(|p| (p.2, p.3, p.4, p.5, p.0, p.1));
        got_sorted.sort_unstable_by_key(|p| (p.1, p.2, p.3, p.4, p.0));
        for (g, r) in got_sorted.iter().zip(&want_sorted) {
            let pair = (r.0, r.1);
            prop_assert_eq!(*key_of.entry(pair).or_insert(g.0), g.0);
            prop_assert_eq!(*pair_of.entry(g.0).or_insert(pair), pair);
        }
    }
}

/// AprilTag's tile thresholds, transcribed tile by tile: the min and max of each 4x4 tile,
/// both dilated over the 3x3 tiles around (clamped to the image), then `SKIP` (255) or
/// `min + ⌊(max - min) f⌋`.
fn reference_tiles(px: &[u8], w: usize, h: usize, min_diff: u8, fraction_q8: u8) -> Vec<u8> {
    let (tw, th) = (w / 4, h / 4);
    let (mut lo, mut hi) = (vec![255u8; tw * th], vec![0u8; tw * th]);
    for ty in 0..th {
        for tx in 0..tw {
            for dy in 0..4 {
                for dx in 0..4 {
                    let v = px[(4 * ty + dy) * w + 4 * tx + dx];
                    lo[ty * tw + tx] = lo[ty * tw + tx].min(v);
                    hi[ty * tw + tx] = hi[ty * tw + tx].max(v);
                }
            }
        }
    }
    let mut out = vec![0u8; tw * th];
    for ty in 0..th {
        for tx in 0..tw {
            let (mut mn, mut mx) = (255u8, 0u8);
            for y in ty.saturating_sub(1)..(ty + 2).min(th) {
                for x in tx.saturating_sub(1)..(tx + 2).min(tw) {
                    mn = mn.min(lo[y * tw + x]);
                    mx = mx.max(hi[y * tw + x]);
                }
            }
            out[ty * tw + tx] = if mx - mn < min_diff.max(1) {
                255
            } else {
                mn + ((u16::from(mx - mn) * u16::from(fraction_q8)) >> 8) as u8
            };
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The four-tiles-a-word threshold gives the tile-by-tile one, for any width (partial
    /// words at the right), contrast and fraction.
    #[test]
    fn tile_thresholds_match_the_transcription(
        seed in any::<u64>(),
        w in 4usize..60,
        h in 4usize..24,
        min_diff in any::<u8>(),
        fraction_q8 in any::<u8>(),
        spread in 1u32..256,
    ) {
        let mut g = crate::rng::Pcg32::new(seed);
        let base = g.next_u32() % 256;
        let px: Vec<u8> = (0..w * h)
            .map(|_| (base + g.next_u32() % spread).min(255) as u8)
            .collect();
        let src = Sampled::new(ImageView::packed(&px, w, h).unwrap(), 1);
        let mut thr = vec![0u8; tile_count(w, h)];
        let (mut rmin, mut rmax) = (vec![0u8; 3 * (w / 4)], vec![0u8; 3 * (w / 4)]);
        let tiles = build_tiles(&src, min_diff, fraction_q8, &mut thr, &mut rmin, &mut rmax);
        prop_assert_eq!(tiles.thr, &reference_tiles(&px, w, h, min_diff, fraction_q8)[..]);
    }
}

// ---------------------------------------------------------------------------- robustness

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any bytes, any size: a result (a few false tags at most), never a panic.
    #[test]
    fn arbitrary_frames_never_panic(
        seed in any::<u64>(),
        w in 1usize..170,
        h in 1usize..130,
        d in 1u8..4,
        flat in any::<bool>(),
    ) {
        let mut g = crate::rng::Pcg32::new(seed);
        let px: Vec<u8> = (0..w * h).map(|_| if flat { 128 } else { g.next_u32() as u8 }).collect();
        let cfg = DetectorConfig { decimate: d, ..DetectorConfig::default() };
        let det = Detector::new(cfg, &[&TAG36H11, &TAG_STANDARD41H12]).unwrap();
        let mut ws = std::boxed::Box::new(Small::new());
        let frame = ImageView::packed(&px, w, h).unwrap();
        let r: crate::Result<heapless::Vec<Detection, 4>> =
            det.detect(&frame, &mut ws.as_mut_view());
        // The workspace holds 160 columns and 160x120 worth of tiles: a wider frame is a
        // width error, a taller one (of at most 160 columns) a tiles error; nothing else.
        let (sw, sh) = (w.div_ceil(usize::from(d)), h.div_ceil(usize::from(d)));
        match r {
            Ok(_) => prop_assert!(
                sw < 8 || sh < 8 || (sw <= 160 && tiles_len(sw, sh, 1) <= tiles_len(160, 120, 1))
            ),
            Err(crate::Error::BufferTooSmall("workspace.width")) => prop_assert!(sw > 160),
            Err(crate::Error::BufferTooSmall("workspace.tiles")) => {
                prop_assert!(sw <= 160 && tiles_len(sw, sh, 1) > tiles_len(160, 120, 1));
            }
            Err(e) => prop_assert!(false, "unexpected error {:?}", e),
        }
    }
}

#[test]
fn capacities_cut_work_without_failing() {
    let (w, h) = (160, 120);
    let mut g = crate::rng::Pcg32::new(5);
    let mut px: Vec<u8> = (0..w * h).map(|_| g.next_u32() as u8).collect();
    draw(&mut px, w, &TAG36H11, 3, (100, 60), 5, 0);
    let det = Detector::new(DetectorConfig::default(), &[&TAG36H11]).unwrap();
    // 64 labels for a frame of noise: most of it is skipped, counted, no panic.
    let mut tiny =
        std::boxed::Box::new(Workspace::<160, { tiles_len(160, 120, 1) }, 64, 8, 256, 256>::new());
    let frame = ImageView::packed(&px, w, h).unwrap();
    let _: heapless::Vec<Detection, 2> = det.detect(&frame, &mut tiny.as_mut_view()).unwrap();
    let s = *tiny.stats();
    assert_eq!(s.labels, 64);
    assert!(s.label_overflow > 0, "{s:?}");
    // An output of one keeps one.
    let mut ws = std::boxed::Box::new(Small::new());
    let mut px2 = vec![140u8; w * h];
    draw(&mut px2, w, &TAG36H11, 1, (10, 10), 5, 0);
    draw(&mut px2, w, &TAG36H11, 2, (90, 50), 5, 0);
    let one: heapless::Vec<Detection, 1> = det
        .detect(
            &ImageView::packed(&px2, w, h).unwrap(),
            &mut ws.as_mut_view(),
        )
        .unwrap();
    assert_eq!(one.len(), 1);
    assert_eq!(ws.stats().dropped, 1);
}

#[test]
fn bad_configuration_and_buffers_are_named_errors() {
    let bad = |cfg: DetectorConfig, name: &'static str| {
        assert_eq!(
            Detector::new(cfg, &[&TAG36H11]).err(),
            Some(crate::Error::InvalidParameter(name))
        );
    };
    let d = DetectorConfig::default();
    bad(DetectorConfig { decimate: 0, ..d }, "decimate");
    bad(DetectorConfig { decimate: 9, ..d }, "decimate");
    bad(
        DetectorConfig {
            max_hamming: 4,
            ..d
        },
        "max_hamming",
    );
    bad(
        DetectorConfig {
            min_white_black_diff: 0,
            ..d
        },
        "min_white_black_diff",
    );
    bad(
        DetectorConfig {
            max_nmaxima: 3,
            ..d
        },
        "max_nmaxima",
    );
    bad(
        DetectorConfig {
            critical_angle_deg: f32::NAN,
            ..d
        },
        "critical_angle_deg",
    );
    bad(
        DetectorConfig {
            max_line_fit_mse: 0.0,
            ..d
        },
        "max_line_fit_mse",
    );
    bad(
        DetectorConfig {
            decode_sharpening: -1.0,
            ..d
        },
        "decode_sharpening",
    );
    bad(
        DetectorConfig {
            min_decision_margin: f32::INFINITY,
            ..d
        },
        "min_decision_margin",
    );
    bad(
        DetectorConfig {
            max_batches: 0,
            ..d
        },
        "max_batches",
    );
    // 2 bits on tag16h5 (distance 5) is allowed, 3 is not.
    assert!(Detector::new(d, &[&TAG16H5]).is_ok());
    assert_eq!(
        Detector::new(
            DetectorConfig {
                max_hamming: 3,
                ..d
            },
            &[&TAG16H5]
        )
        .err(),
        Some(crate::Error::InvalidParameter("max_hamming"))
    );
    assert_eq!(
        Detector::new(d, &[]).err(),
        Some(crate::Error::InvalidParameter("families"))
    );
    let det = Detector::new(d, &[&TAG36H11]).unwrap();
    let px = vec![0u8; 400 * 10];
    let mut ws = std::boxed::Box::new(Small::new());
    let r: crate::Result<heapless::Vec<Detection, 1>> = det.detect(
        &ImageView::packed(&px, 400, 10).unwrap(),
        &mut ws.as_mut_view(),
    );
    assert_eq!(
        r.err(),
        Some(crate::Error::BufferTooSmall("workspace.width"))
    );
    let r: crate::Result<heapless::Vec<Detection, 1>> = det.detect(
        &ImageView::packed(&px, 150, 26).unwrap(),
        &mut ws.as_mut_view(),
    );
    assert!(r.unwrap().is_empty());
    // Tiny frames give nothing, no error.
    let r: crate::Result<heapless::Vec<Detection, 1>> = det.detect(
        &ImageView::packed(&px, 7, 7).unwrap(),
        &mut ws.as_mut_view(),
    );
    assert!(r.unwrap().is_empty());
    let mut no_sort =
        std::boxed::Box::new(Workspace::<160, { tiles_len(160, 120, 1) }, 64, 8, 256, 8>::new());
    let r: crate::Result<heapless::Vec<Detection, 1>> = det.detect(
        &ImageView::packed(&px, 150, 26).unwrap(),
        &mut no_sort.as_mut_view(),
    );
    assert_eq!(
        r.err(),
        Some(crate::Error::BufferTooSmall("workspace.sort"))
    );
}

// ----------------------------------------------------------------------------------- pose

#[test]
fn tag_pose_is_apriltags_tag_frame() {
    let cam = Camera::pinhole(Intrinsics::new(500.0f32, 500.0, 320.0, 240.0).unwrap());
    let size = 0.12f32;
    let truth = Pose::from_rodrigues(
        Vector3::new(0.3f32, -0.4, 0.2),
        Vector3::new(0.05, -0.02, 0.8),
    )
    .unwrap();
    // Corner i is (s/2) CORNER_TAG_COORDS[i] in the tag frame.
    let corners = CORNER_TAG_COORDS.map(|(x, y)| {
        cam.project(&truth, &Point3::new(0.5 * size * x, 0.5 * size * y, 0.0))
            .unwrap()
    });
    let det = Detection {
        family: &TAG36H11,
        id: 0,
        hamming: 0,
        decision_margin: 50.0,
        corners,
        center: corners[0],
        homography: crate::homography::Homography::identity(),
    };
    let p = tag_pose(&det, size, &cam, &PlanarConfig::default()).unwrap();
    let dr = (p.best.pose.isometry().rotation * truth.isometry().rotation.inverse()).angle();
    // f32 through IPPE and LM: 1e-3 rad, 0.1 mm.
    assert!(dr < 1e-3, "{dr}");
    assert!((p.best.pose.translation() - truth.translation()).norm() < 1e-4);
    // Fronto-parallel and upright: R = I, the top-left corner (tag (-1, -1)) up and left.
    let flat = Pose::from_rodrigues(Vector3::zeros(), Vector3::new(0.0, 0.0, 1.0)).unwrap();
    let c = CORNER_TAG_COORDS.map(|(x, y)| {
        cam.project(&flat, &Point3::new(0.06 * x, 0.06 * y, 0.0))
            .unwrap()
    });
    assert!(c[3].x < 320.0 && c[3].y < 240.0);
    assert_eq!(
        tag_pose(&det, 0.0, &cam, &PlanarConfig::default()).err(),
        Some(crate::Error::InvalidParameter("tag_size"))
    );
}

#[test]
fn workspace_bytes_match_the_table() {
    // The table of the type's docs counts the buffers' bytes; the struct adds its counters and
    // padding.
    let table =
        |w: usize, tiles: usize, labels: usize, clusters: usize, points: usize, sort: usize| {
            tiles + 2 * w + 16 * w + 3 * labels + 32 * clusters + 4 * points + 2 * sort
        };
    let est = table(
        320,
        tiles_len(320, 240, 1),
        8192,
        512,
        16384,
        sort_len(320, 240, 1),
    );
    assert!(Workspace320x240::BYTES >= est && Workspace320x240::BYTES < est + 256);
    let bytes = Workspace320x240::BYTES;
    assert!(bytes < 150 * 1024, "{bytes}");
    std::println!(
        "Workspace320x240 {} B, Workspace640x480 {} B",
        Workspace320x240::BYTES,
        Workspace640x480::BYTES
    );
}

/// The workspace is built in a `static` (what a board does with it): `new` is `const`.
static _WORKSPACE: Workspace<64, { tiles_len(64, 64, 1) }, 256, 32, 256, 256> = Workspace::new();
