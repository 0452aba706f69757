//! AprilTag detection on frames of arbitrary geometry (sizes, strides, short buffers) holding
//! rendered tags of any family (arbitrary id, cell size, placement, rotation, contrast) over
//! the fuzzer's bytes, with arbitrary configurations (decimation, `max_hamming`, thresholds),
//! family sets and three workspaces: two fixed `u16` ones (a board's) and one of `u32` labels
//! whose buffers are sized at run time from the input (a host's, each buffer's length from
//! the frame's `const fn` sizes scaled, short ones included); then each family's decoder on arbitrary words and on
//! rotated codes with flipped bits. Contract (`Detector::new`, `detect`, `Family::decode`
//! docs): no panic; every detection is of a family asked for, with an id in the family,
//! `hamming ≤ max_hamming`, a finite margin `≥ min_decision_margin`, finite corners and
//! centre; detections sorted by id; a decode's id is in the family, its Hamming distance
//! `≤ min(max_hamming, 3)` and equal to the distance between the code and the word in the
//! rotation reported; a code with at most `max_hamming` flipped bits (`2 max_hamming <
//! min_distance`) decodes to its own id.
//!
//! Tracking by detection on the same frames: `Detector::refine_target`, `refine_detection` and
//! `find_target_near` from an arbitrary prediction (any floats, non-finite ones included, or a
//! rendered tag's corners moved by the fuzzer) of an arbitrary family and id. Contract (their docs): no
//! panic; `refine_target` gives finite corners within 8 px of a finite prediction and
//! `refine_detection` the same corners in AprilTag's order, the id and `hamming ≤ max_hamming`;
//! `find_target_near` errs only with a `workspace.*` buffer and gives finite corners;
//! `refine_partial` gives finite corners within 8 px, the id, seen cells within the budget
//! (itself within `max_hamming`) and edges of at least 8 inliers spanning half their length, or
//! a refusal.
//!
//! AprilGrid: bit 4 of the family set adds the 2-cell-border tag36h11 (`TAG36H11_B2`, also
//! among the drawn families), the threshold fraction is the fuzzer's, and on the full
//! workspace a 3x2 `AprilGrid`'s `detect_corners` (with the saddle refinement) runs on the same
//! frame. Contract (its docs): an error only for a detector without the family or a
//! `workspace.*` buffer; the corners' ids ascend, below the grid's points, their pixels
//! finite.
//!
//! ArUco: the families include OpenCV's dictionaries (`families::ARUCO`, drawn by
//! `Family::cell` like the AprilTag families, mixed into the detector's set), with arbitrary
//! `error_correction_rate` and `max_erroneous_bits_in_border_rate`. Contract: a detection's
//! `hamming` is within `Detector::max_hamming_for` its family; a decode is exact (OpenCV's
//! `identify`): the smallest id within `min(max_hamming, max_correctable)` bits in some
//! rotation, and `None` only when there is none (checked against every code).
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::aprilgrid::{AprilGrid, GridCorner};
use camgeom::apriltag::family::MAX_CORRECTABLE;
use camgeom::apriltag::quad::Cluster;
use camgeom::apriltag::segment::Run;
use camgeom::apriltag::{
    Detection, Detector, DetectorConfig, Family, Label, Stats, Workspace, WorkspaceView, families,
    rotate90, sort_len, tiles_len,
};
use camgeom::image::ImageView;
use camgeom::nalgebra::Point2;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Geometry, Num};

/// A small workspace: frames up to 64 pixels wide (decimated), few labels and points.
type Small = Workspace<64, 256, 512, 64, 1024, 512>;
type Full = camgeom::apriltag::Workspace320x240;

#[derive(Debug, Arbitrary)]
struct Tag {
    family: u8,
    id: u16,
    /// Pixels a cell: 1 + cell % 12.
    cell: u8,
    origin: (u8, u8),
    /// Rotation, 1/256 turns.
    angle: u8,
    dark: u8,
    light: u8,
}

#[derive(Debug, Arbitrary)]
struct Cfg {
    decimate: u8,
    refine_edges: bool,
    decode_sharpening: Num,
    min_white_black_diff: u8,
    min_cluster_pixels: u16,
    max_nmaxima: u8,
    critical_angle_deg: Num,
    max_line_fit_mse: Num,
    min_decision_margin: Num,
    min_edge_gradient: u8,
    reject_clipped: bool,
    max_batches: u8,
    max_quads: u16,
    threshold_fraction: Num,
}

#[derive(Debug, Arbitrary)]
struct Input {
    geometry: Geometry,
    background: std::vec::Vec<u8>,
    tags: std::vec::Vec<Tag>,
    /// Bit `i` selects `families::ALL[i]`.
    families: u8,
    max_hamming: u8,
    /// `None`: the defaults (with the fuzzer's `max_hamming`).
    cfg: Option<Cfg>,
    small_workspace: bool,
    /// `Some`: a run-time-sized `u32`-label workspace instead, each buffer's length a fraction
    /// `(k + 1) / 8` of the frame's size (`k = byte % 10`: short, exact and long buffers) and
    /// the label, cluster and point capacities from the fuzzer.
    host: Option<([u8; 5], u16, u16, u16)>,
    words: std::vec::Vec<(u8, u64, u8)>,
    flips: std::vec::Vec<(u8, u16, u8, [u8; 3])>,
    /// Predictions for the tracking calls: family, id, four corners (arbitrary numbers, or
    /// with `near` the first tag's square corners moved by them, in 1/16 px).
    predictions: std::vec::Vec<(u8, u16, [(Num, Num); 4], Option<[(i8, i8); 4]>)>,
    /// ArUco dictionaries added to the detector's families: indices into `families::ARUCO`.
    aruco: std::vec::Vec<u8>,
    /// `Some((e, b))`: `error_correction_rate` and `max_erroneous_bits_in_border_rate`.
    aruco_rates: Option<(Num, Num)>,
}

/// Family `i` of the AprilTag families, then OpenCV's ArUco dictionaries, then the
/// 2-cell-border tag36h11.
fn family(i: u8) -> &'static Family {
    let n = families::ALL.len() + families::ARUCO.len() + 1;
    let i = usize::from(i) % n;
    match families::ALL.get(i) {
        Some(f) => f,
        None => families::ARUCO
            .get(i - families::ALL.len())
            .copied()
            .unwrap_or(&families::TAG36H11_B2),
    }
}

/// A 3x2 AprilGrid's corners of the frame (module docs).
fn aprilgrid(det: &Detector, view: &ImageView<'_, u8>, ws: &mut WorkspaceView<'_, u16>) {
    let Ok(grid) = AprilGrid::new(3, 2, 0.03, 0.3) else {
        panic!("a valid grid refused");
    };
    let mut tags = camgeom::heapless::Vec::<Detection, 8>::new();
    let mut out = [GridCorner::default(); 24];
    let has = det.families().contains(&grid.family());
    let saddle = camgeom::chessboard::SaddleConfig::default().check().ok();
    match grid.detect_corners(det, view, ws, &mut tags, saddle.as_ref(), &mut out) {
        Ok(n) => {
            assert!(has && n <= 24, "aprilgrid: {n}");
            let c = &out[..n];
            assert!(c.windows(2).all(|w| w[0].id < w[1].id), "aprilgrid: order");
            assert!(
                c.iter()
                    .all(|c| c.id < 24 && c.point.x.is_finite() && c.point.y.is_finite())
            );
        }
        Err(Error::InvalidParameter("detector")) => assert!(!has),
        Err(Error::BufferTooSmall(b)) => assert!(b.starts_with("workspace."), "{b}"),
        Err(e) => panic!("aprilgrid: {e:?}"),
    }
}

/// The smallest id within `maxh` bits of `word` in some rotation, by comparing every code.
fn brute_decode(f: &Family, word: u64, maxh: u8) -> Option<u16> {
    let mut r = word;
    let mut best: Option<u16> = None;
    for _ in 0..4 {
        for id in 0..f.ncodes() as u16 {
            let c = f.code(id).unwrap_or(0);
            if (c ^ r).count_ones() <= u32::from(maxh) && best.is_none_or(|b| id < b) {
                best = Some(id);
            }
        }
        r = rotate90(r, f.nbits());
    }
    best
}

fn config(inp: &Input) -> DetectorConfig {
    let mut cfg = DetectorConfig {
        max_hamming: inp.max_hamming % 5,
        ..DetectorConfig::default()
    };
    if let Some(c) = &inp.cfg {
        cfg = DetectorConfig {
            decimate: c.decimate % 10,
            refine_edges: c.refine_edges,
            decode_sharpening: c.decode_sharpening.get(),
            max_hamming: cfg.max_hamming,
            min_white_black_diff: c.min_white_black_diff,
            min_cluster_pixels: c.min_cluster_pixels,
            max_nmaxima: c.max_nmaxima % 16,
            critical_angle_deg: c.critical_angle_deg.get(),
            max_line_fit_mse: c.max_line_fit_mse.get(),
            min_decision_margin: c.min_decision_margin.get(),
            min_edge_gradient: c.min_edge_gradient,
            reject_clipped: c.reject_clipped,
            max_batches: c.max_batches % 6,
            // At most 64 quads: each is an edge refinement and a decode per family.
            max_quads: c.max_quads % 64,
            threshold_fraction: c.threshold_fraction.get(),
            ..cfg
        };
    }
    if let Some((e, b)) = inp.aruco_rates {
        cfg.error_correction_rate = f64::from(e.get());
        cfg.max_erroneous_bits_in_border_rate = f64::from(b.get());
    }
    cfg
}

fn render(inp: &Input, stride: usize, len: usize) -> std::vec::Vec<u8> {
    let bg = &inp.background;
    let mut px: std::vec::Vec<u8> = (0..len)
        .map(|i| bg.get(i % bg.len().max(1)).copied().unwrap_or(128))
        .collect();
    let stride = stride.max(1);
    for t in inp.tags.iter().take(3) {
        let f = family(t.family);
        let id = t.id % f.ncodes() as u16;
        let s = 1.0 + f32::from(t.cell % 12);
        let a = f32::from(t.angle) / 256.0 * std::f32::consts::TAU;
        let (c, sn) = (a.cos(), a.sin());
        let wab = i32::from(f.width_at_border());
        let lo = (wab - i32::from(f.total_width())) / 2;
        for (i, p) in px.iter_mut().enumerate() {
            let (dx, dy) = (
                (i % stride) as f32 - f32::from(t.origin.0),
                (i / stride) as f32 - f32::from(t.origin.1),
            );
            let (u, v) = ((c * dx + sn * dy) / s, (-sn * dx + c * dy) / s);
            if let Some(white) = f.cell(id, u.floor() as i32 + lo, v.floor() as i32 + lo) {
                *p = if white { t.light } else { t.dark };
            }
        }
    }
    px
}

fn check(dets: &[Detection], det: &Detector, w: usize, h: usize) {
    let cfg = det.config();
    for d in dets {
        assert!(det.families().contains(&d.family), "family not asked for");
        assert!(
            usize::from(d.id) < d.family.ncodes(),
            "id {} outside {}",
            d.id,
            d.family.name()
        );
        let bound = det.max_hamming_for(d.family);
        assert!(
            d.hamming <= bound && (d.family.is_aruco() || bound == cfg.max_hamming),
            "hamming {} > {bound}",
            d.hamming,
        );
        assert!(
            d.decision_margin.is_finite() && d.decision_margin >= cfg.min_decision_margin,
            "decision margin {}",
            d.decision_margin
        );
        for p in d.corners.iter().chain([&d.center]) {
            assert!(
                p.x.is_finite() && p.y.is_finite(),
                "corner {p:?} of a {w}x{h} frame"
            );
        }
    }
    assert!(
        dets.windows(2).all(|p| p[0].id <= p[1].id),
        "not sorted by id"
    );
}

fn detect(det: &Detector, view: &ImageView<'_, u8>, ws: &mut WorkspaceView<'_, impl Label>) {
    let (w, h) = (view.width(), view.height());
    match det.detect::<8>(view, ws) {
        Ok(d) => check(&d, det, w, h),
        Err(Error::BufferTooSmall(b)) => assert!(b.starts_with("workspace."), "buffer {b}"),
        Err(e) => panic!("detect: undocumented error {e:?}"),
    }
}

/// The first tag's outer border corners (top-left, top-right, bottom-right, bottom-left of
/// the unrotated tag), where `render` draws it.
fn tag_square(inp: &Input) -> Option<[Point2<f32>; 4]> {
    let t = inp.tags.first()?;
    let f = family(t.family);
    let s = 1.0 + f32::from(t.cell % 12);
    let a = f32::from(t.angle) / 256.0 * std::f32::consts::TAU;
    let (c, sn) = (a.cos(), a.sin());
    let side = s * f32::from(f.width_at_border());
    let lo = s * (f32::from(f.total_width()) - f32::from(f.width_at_border())) / 2.0;
    Some(
        [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(u, v)| {
            let (u, v) = (lo + u * side, lo + v * side);
            // `render`'s inverse rotation.
            Point2::new(
                f32::from(t.origin.0) + c * u - sn * v - 0.5,
                f32::from(t.origin.1) + sn * u + c * v - 0.5,
            )
        }),
    )
}

fn track(
    inp: &Input,
    det: &Detector,
    view: &ImageView<'_, u8>,
    ws: &mut WorkspaceView<'_, impl Label>,
) {
    for (f, id, pts, near) in inp.predictions.iter().take(4) {
        let f = family(*f);
        let mut predicted = pts.map(common::pt2);
        if let (Some(moves), Some(square)) = (near, tag_square(inp)) {
            for ((p, q), (dx, dy)) in predicted.iter_mut().zip(square).zip(moves) {
                *p = Point2::new(q.x + f32::from(*dx) / 16.0, q.y + f32::from(*dy) / 16.0);
            }
        }
        let refined = det.refine_target(view, f, *id, &predicted);
        if let Some(c) = refined {
            for (p, q) in c.iter().zip(predicted.iter()) {
                assert!(p.x.is_finite() && p.y.is_finite(), "refined {p:?}");
                assert!((p - q).norm() <= 8.0 + 1e-3, "refined {p:?} from {q:?}");
            }
        }
        // As a detection: the same corners (AprilTag's order), its id, within max_hamming.
        let again = det.refine_detection(view, f, *id, &predicted);
        assert_eq!(
            again.is_some(),
            refined.is_some(),
            "refine_detection vs refine_target"
        );
        if let (Some(d), Some(c)) = (again, refined) {
            assert_eq!(d.corners, [c[3], c[2], c[1], c[0]], "corner order");
            assert!(d.id == *id && d.hamming <= det.max_hamming_for(f), "{d:?}");
            assert!(d.center.x.is_finite() && d.center.y.is_finite(), "{d:?}");
        }
        // A partly seen tag: finite corners within 8 px, its id, the seen cells within the
        // family's budget (at most the detector's bits), the views' counts in range.
        if let Ok(p) = det.refine_partial(view, f, *id, &predicted) {
            let d = &p.detection;
            assert!(d.id == *id && !f.is_aruco(), "{d:?}");
            for (c, q) in d.target_corners().iter().zip(predicted.iter()) {
                assert!(c.x.is_finite() && c.y.is_finite(), "partial {c:?}");
                assert!((c - q).norm() <= 8.0 + 1e-3, "partial {c:?} from {q:?}");
            }
            let v = &p.view;
            assert!(u32::from(v.cells_seen) <= f.nbits(), "{v:?}");
            assert!(d.hamming <= v.cells_budget, "{d:?} {v:?}");
            assert!(v.cells_budget <= det.max_hamming_for(f), "{v:?}");
            for ((s, n), m) in v.edge_span.iter().zip(v.edge_inliers).zip(v.edge_samples) {
                let (n, m) = (u32::from(n), u32::from(m));
                assert!((0.5..=1.0).contains(s) && n >= 8 && 3 * n >= m, "{v:?}");
            }
            assert!(d.decision_margin.is_finite(), "{d:?}");
        }
        match det.find_target_near(view, ws, f, *id, &predicted) {
            Ok(Some(c)) => {
                for p in &c {
                    assert!(p.x.is_finite() && p.y.is_finite(), "region {p:?}");
                }
            }
            Ok(None) => {}
            Err(Error::BufferTooSmall(b)) => assert!(b.starts_with("workspace."), "buffer {b}"),
            Err(e) => panic!("find_target_near: undocumented error {e:?}"),
        }
    }
}

/// A workspace of `u32` labels sized at run time (a host's): the frame's sizes (decimated
/// width, tiles, sort keys) each scaled by `(frac + 1) / 8`, at most 10/8.
fn host(
    det: &Detector,
    view: &ImageView<'_, u8>,
    frac: [u8; 5],
    labels: u16,
    clusters: u16,
    points: u16,
) {
    let d = usize::from(det.config().decimate.max(1));
    let (w, h) = (view.width(), view.height());
    let f = |i: usize, n: usize| n * (usize::from(frac[i] % 10) + 1) / 8;
    let wd = w.div_ceil(d);
    let mut tiles = vec![0u8; f(0, tiles_len(w, h, d))];
    let (mut rmin, mut rmax) = (vec![0u8; f(1, wd)], vec![0u8; f(1, wd)]);
    let (mut r0, mut r1) = (vec![Run::<u32>::empty(); f(2, wd)], vec![Run::empty(); wd]);
    let labels = usize::from(labels % 4096);
    let (mut parent, mut size) = (vec![0u32; labels], vec![0u8; f(3, labels)]);
    let mut slots = vec![Cluster::<u64>::empty(); usize::from(clusters % 512)];
    let mut pts = vec![0u32; usize::from(points % 8192)];
    let mut keys = vec![0u16; f(4, sort_len(w, h, d))];
    let mut stats = Stats::default();
    let mut ws = WorkspaceView::with_labels(
        &mut tiles,
        &mut rmin,
        &mut rmax,
        [&mut r0, &mut r1],
        &mut parent,
        &mut size,
        &mut slots,
        &mut pts,
        &mut keys,
        &mut stats,
    );
    detect(det, view, &mut ws);
    let s = ws.stats();
    assert!(s.labels as usize <= labels, "{s:?}");
}

fuzz_target!(|inp: Input| {
    let fams: std::vec::Vec<&'static Family> = (0..4)
        .filter(|i| inp.families & (1 << i) != 0)
        .map(|i| families::ALL[i])
        .chain((inp.families & 16 != 0).then_some(&families::TAG36H11_B2))
        .chain(
            inp.aruco
                .iter()
                .take(4)
                .map(|&k| families::ARUCO[usize::from(k) % families::ARUCO.len()]),
        )
        .collect();
    let cfg = config(&inp);
    if let Ok(det) = Detector::new(cfg, &fams) {
        assert!(cfg.max_hamming <= MAX_CORRECTABLE);
        // Any geometry, at most 80 K pixels of buffer: larger ones meet a short buffer.
        let (w, h, s, len) = inp.geometry.dims(80 << 10);
        let data = render(&inp, s, len);
        if let Ok(view) = ImageView::new(&data[..], w, h, s) {
            if let Some((frac, labels, clusters, points)) = inp.host {
                host(&det, &view, frac, labels, clusters, points);
            } else if inp.small_workspace {
                let mut ws = std::boxed::Box::new(Small::new());
                detect(&det, &view, &mut ws.as_mut_view());
                track(&inp, &det, &view, &mut ws.as_mut_view());
            } else {
                let mut ws = std::boxed::Box::new(Full::new());
                detect(&det, &view, &mut ws.as_mut_view());
                track(&inp, &det, &view, &mut ws.as_mut_view());
                aprilgrid(&det, &view, &mut ws.as_mut_view());
            }
        }
    }

    // The decoders.
    for &(f, word, mh) in inp.words.iter().take(8) {
        let f = family(f);
        let got = f.decode(word, mh);
        let bound = mh.min(f.max_correctable());
        assert_eq!(
            got.map(|d| d.id),
            brute_decode(f, word, bound),
            "decode: {} not the smallest id within {bound}",
            f.name()
        );
        if let Some(d) = got {
            assert!(usize::from(d.id) < f.ncodes(), "decode: id {}", d.id);
            assert!(d.hamming <= bound && d.rotation < 4, "decode: {d:?}");
            let mut r = word;
            for _ in 0..d.rotation {
                r = rotate90(r, f.nbits());
            }
            let code = f.code(d.id).unwrap_or(0);
            assert_eq!(
                (code ^ r).count_ones(),
                u32::from(d.hamming),
                "decode: distance"
            );
        }
    }
    for &(f, id, rot, bits) in inp.flips.iter().take(8) {
        let f = family(f);
        let id = id % f.ncodes() as u16;
        let Some(mut word) = f.code(id) else {
            panic!("code of id {id} below ncodes");
        };
        for _ in 0..rot % 4 {
            word = rotate90(word, f.nbits());
        }
        let mut flipped = 0u64;
        for b in bits.iter().take(MAX_CORRECTABLE as usize) {
            flipped |= 1 << (u32::from(*b) % f.nbits());
        }
        let mh = flipped.count_ones() as u8;
        if 2 * u32::from(mh) < u32::from(f.min_distance()) && mh <= f.max_correctable() {
            let d = f.decode(word ^ flipped, mh);
            assert_eq!(d.map(|d| d.id), Some(id), "{}: {mh} flipped bits", f.name());
        }
    }
});
