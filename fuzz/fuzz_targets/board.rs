//! Tag boards (`apriltag::board`): a board from arbitrary bytes — a `GridBoard` of any shape,
//! sizes (non-finite, negative, huge included) and first id, or up to 8 listed tags of any ids
//! and corners — of an AprilTag family or an ArUco dictionary, then the board pose from up to
//! 12 arbitrary detections (any family of the set, any id, any corners: often the board's own
//! tags projected by an arbitrary pose and moved by the fuzzer, so the solver runs past its
//! checks) through an arbitrary pinhole camera with distortion, into buffers of 8 or 64 points.
//!
//! Contract (`TagBoard::new`, `GridBoard::fill`, `board_pose` docs): no panic; a board that
//! builds has ids in its family, unique, and finite corners; `grid_tags` equals
//! `GridBoard::tag` for every tag; an `Ok` pose has a finite rotation and translation, an RMS
//! error at most `max_rms_px`, `points == 4 tags`, at least one tag and no more tags than
//! distinct board ids detected; the errors are those the docs name.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::apriltag::{
    BoardBuffers, BoardConfig, BoardTag, Detection, Family, GridBoard, TagBoard, board_pose,
    families, grid_tags,
};
use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::nalgebra::{Point2, Point3};
use camgeom::transform::Pose;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Num, detection, pt2, vec3};

const FAMILIES: [&Family; 4] = [
    &families::DICT_4X4_50,
    &families::TAG36H11,
    &families::DICT_6X6_250,
    &families::TAG16H5,
];

#[derive(Debug, Arbitrary)]
enum Layout {
    Grid {
        markers_x: u8,
        markers_y: u8,
        length: Num,
        separation: Num,
        first_id: u16,
    },
    Listed(Vec<(u16, [(Num, Num, Num); 4])>),
}

#[derive(Debug, Arbitrary)]
enum Det {
    /// Board tag `k`'s corners through the pose, each moved by the fuzzer's pixels.
    Projected {
        k: u8,
        moves: [(Num, Num); 4],
        family: u8,
    },
    /// Anything.
    Free {
        family: u8,
        id: u16,
        corners: [(Num, Num); 4],
    },
}

#[derive(Debug, Arbitrary)]
struct Input {
    family: u8,
    layout: Layout,
    rvec: (Num, Num, Num),
    tvec: (Num, Num, Num),
    f: Num,
    k1: Num,
    dets: Vec<Det>,
    max_rms_px: Num,
    ambiguity_ratio: Num,
    small: bool,
}

fn check<const N: usize>(
    board: &TagBoard<'_, f32>,
    dets: &[Detection],
    cam: &Camera<f32>,
    cfg: &BoardConfig,
) {
    let mut buf = BoardBuffers::<f32, N>::new();
    match board_pose(board, dets, cam, cfg, &mut buf) {
        Ok(p) => {
            let t = p.estimate.pose.translation();
            assert!(t.iter().all(|v| v.is_finite()));
            assert!(
                p.estimate
                    .pose
                    .rotation()
                    .matrix()
                    .iter()
                    .all(|v| v.is_finite())
            );
            assert!(p.estimate.rms_px <= cfg.max_rms_px, "{p:?}");
            assert!(p.tags >= 1 && usize::from(p.points) == 4 * usize::from(p.tags));
            let mut ids: Vec<u16> = dets
                .iter()
                .filter(|d| d.family.name() == board.family().name())
                .filter(|d| board.tag(d.id).is_some())
                .map(|d| d.id)
                .collect();
            ids.sort_unstable();
            ids.dedup();
            assert!(usize::from(p.tags) + usize::from(p.duplicates) <= ids.len());
        }
        Err(
            Error::TooFewPoints
            | Error::BufferTooSmall("buffers")
            | Error::NoConvergence
            | Error::Degenerate
            | Error::NonFinite
            | Error::BehindCamera
            | Error::AtInfinity
            | Error::Overflow
            | Error::InvalidParameter(_),
        ) => {}
        Err(e) => panic!("unexpected error {e:?}"),
    }
}

fuzz_target!(|inp: Input| {
    let family = FAMILIES[usize::from(inp.family) % FAMILIES.len()];
    let mut store = [BoardTag {
        id: 0,
        corners: [[0.0f32; 3]; 4],
    }; 64];
    let board = match &inp.layout {
        Layout::Grid {
            markers_x,
            markers_y,
            length,
            separation,
            first_id,
        } => {
            let grid = GridBoard {
                markers_x: u16::from(*markers_x % 9),
                markers_y: u16::from(*markers_y % 9),
                marker_length: length.get(),
                marker_separation: separation.get(),
                first_id: *first_id,
            };
            // The const layout is the run-time one.
            const C: [BoardTag; 12] = grid_tags(4, 0.04, 0.01, 2);
            let g = GridBoard::<f32> {
                markers_x: 4,
                markers_y: 3,
                marker_length: 0.04,
                marker_separation: 0.01,
                first_id: 2,
            };
            for (k, c) in C.iter().enumerate() {
                assert_eq!(Some(*c), g.tag(k));
            }
            match grid.fill(family, &mut store) {
                Ok(b) => b,
                Err(
                    Error::InvalidParameter(_) | Error::BufferTooSmall("out") | Error::TooFewPoints,
                ) => return,
                Err(e) => panic!("unexpected error {e:?}"),
            }
        }
        Layout::Listed(tags) => {
            let n = tags.len().min(8);
            for (slot, (id, c)) in store.iter_mut().zip(tags.iter().take(8)) {
                *slot = BoardTag {
                    id: *id,
                    corners: c.map(|p| [p.0.get(), p.1.get(), p.2.get()]),
                };
            }
            match TagBoard::new(family, &store[..n]) {
                Ok(b) => b,
                Err(Error::InvalidParameter("tags") | Error::TooFewPoints) => return,
                Err(e) => panic!("unexpected error {e:?}"),
            }
        }
    };
    for (k, t) in board.tags().iter().enumerate() {
        assert!(usize::from(t.id) < family.ncodes());
        assert!(t.corners.iter().flatten().all(|v| v.is_finite()));
        assert!(board.tags()[..k].iter().all(|o| o.id != t.id));
    }
    let f = inp.f.get().abs().clamp(1.0, 5000.0);
    let Ok(k) = Intrinsics::new(f, f, 160.0, 120.0) else {
        return;
    };
    let k1 = inp.k1.get();
    let Ok(dist) = Distortion::from_opencv([
        if k1.is_finite() {
            k1.clamp(-1.0, 1.0)
        } else {
            0.0
        },
        0.0,
        0.0,
        0.0,
        0.0,
    ]) else {
        return;
    };
    let cam = Camera::new(k, dist);
    let pose = Pose::from_rodrigues(vec3(inp.rvec), vec3(inp.tvec)).ok();
    let mut dets = Vec::new();
    for d in inp.dets.iter().take(12) {
        match d {
            Det::Projected {
                k,
                moves,
                family: fam,
            } => {
                let Some(tag) = board.tags().get(usize::from(*k) % board.tags().len()) else {
                    continue;
                };
                let Some(pose) = pose.as_ref() else { continue };
                let mut c = [Point2::origin(); 4];
                let mut ok = true;
                for ((u, x), m) in c.iter_mut().zip(&tag.corners).zip(moves) {
                    match cam.project(pose, &Point3::new(x[0], x[1], x[2])) {
                        Ok(p) => *u = p + pt2(*m).coords * 1e-3,
                        Err(_) => ok = false,
                    }
                }
                let fam = if *fam % 4 == 0 {
                    FAMILIES[usize::from(*fam / 4) % 4]
                } else {
                    family
                };
                if ok {
                    dets.push(detection(fam, tag.id, c));
                }
            }
            Det::Free {
                family: fam,
                id,
                corners,
            } => {
                dets.push(detection(
                    FAMILIES[usize::from(*fam) % FAMILIES.len()],
                    *id,
                    corners.map(pt2),
                ));
            }
        }
    }
    let cfg = BoardConfig {
        max_rms_px: inp.max_rms_px.get(),
        ambiguity_ratio: inp.ambiguity_ratio.get(),
        ..BoardConfig::default()
    };
    if inp.small {
        check::<8>(&board, &dets, &cam, &cfg);
    } else {
        check::<64>(&board, &dets, &cam, &cfg);
    }
});
