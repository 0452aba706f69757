//! Vanishing points on arbitrary `f32` segments (NaN, inf, huge, tiny, coincident endpoints,
//! duplicated or collinear segments) and configurations: `VanishingConfig::check`,
//! `find_vanishing_points` (buffers of any length), `fit_vanishing_point`, `horizon` with and
//! without intrinsics. Contract: no panic; a found point has homogeneous coordinates that are
//! finite, its segment count is that of its labels, labels are `NO_POINT` or below the count,
//! and a horizon is a finite line.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::Point2;
use camgeom::vanishing::{
    MAX_POINTS, NO_POINT, Segment, VanishingConfig, VanishingPoint, find_vanishing_points,
    fit_vanishing_point, horizon,
};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Edit, Num, Ransac, apply_edits, finite, pt2};

#[derive(Debug, Arbitrary)]
struct Input {
    segments: std::vec::Vec<((Num, Num), (Num, Num))>,
    edits: std::vec::Vec<Edit>,
    ransac: Ransac,
    min_segments: u8,
    max_points: u8,
    min_length: Num,
    /// Lengths of the label, index and mask buffers relative to the segments (-2..=2).
    slack: [i8; 3],
    out_len: u8,
    /// fx, fy, cx, cy of the camera handed to `horizon`.
    camera: Option<(Num, Num, Num, Num)>,
}

fn check_point(v: &VanishingPoint<f32>, what: &str) {
    assert!(
        finite(v.point.coords().as_slice()),
        "{what}: point not finite"
    );
    assert!(
        finite(v.direction.as_slice()) && v.direction.y >= 0.0,
        "{what}: direction {:?}",
        v.direction
    );
}

fuzz_target!(|inp: Input| {
    let n = inp.segments.len().min(64);
    // Endpoints as points (2k, 2k + 1), so the common edits (duplicate, collinear, scale) reach
    // them.
    let mut ends: std::vec::Vec<Point2<f32>> = inp.segments[..n]
        .iter()
        .flat_map(|s| [pt2(s.0), pt2(s.1)])
        .collect();
    apply_edits(&mut ends, &inp.edits[..inp.edits.len().min(8)]);
    let segments: std::vec::Vec<Segment<f32>> = ends
        .chunks_exact(2)
        .map(|c| Segment::new(c[0], c[1]))
        .collect();

    let config = VanishingConfig {
        ransac: inp.ransac.config(),
        min_segments: usize::from(inp.min_segments % 16),
        max_points: usize::from(inp.max_points % (MAX_POINTS as u8 + 2)),
        min_length: inp.min_length.get(),
    };
    let len = |k: usize| (n as i64 + i64::from(inp.slack[k] % 3)).max(0) as usize;
    let (mut labels, mut index, mut mask) = (
        std::vec![0u8; len(0)],
        std::vec![0u32; len(1)],
        std::vec![false; len(2)],
    );
    let mut out = std::vec![VanishingPoint::default(); usize::from(inp.out_len % 10)];
    let camera = inp
        .camera
        .and_then(|(fx, fy, cx, cy)| Intrinsics::new(fx.get(), fy.get(), cx.get(), cy.get()).ok());

    if let Ok(params) = config.check()
        && let Ok(count) = find_vanishing_points(
            &segments,
            &params,
            &mut labels,
            &mut index,
            &mut mask,
            &mut out,
        )
    {
        assert!(
            count <= out.len() && count <= config.max_points,
            "count {count}"
        );
        for (k, v) in out[..count].iter().enumerate() {
            check_point(v, "find_vanishing_points");
            let mine = labels[..n].iter().filter(|&&l| usize::from(l) == k).count();
            assert_eq!(mine, v.segments, "segments of point {k}");
            assert!(v.segments >= config.min_segments, "support of point {k}");
        }
        assert!(
            labels[..n]
                .iter()
                .all(|&l| l == NO_POINT || usize::from(l) < count),
            "labels"
        );
        for cam in [None, camera.as_ref()] {
            if let Ok((line, _)) = horizon(&out[..count], cam) {
                assert!(finite(line.coords().as_slice()), "horizon not finite");
            }
        }
    }
    // The grouped fit on every other segment, and the horizon of arbitrary points.
    if let Ok(v) = fit_vanishing_point(&segments, |i| i % 2 == 0) {
        check_point(&v, "fit_vanishing_point");
        for cam in [None, camera.as_ref()] {
            if let Ok((line, _)) = horizon(&[v, v, out.first().copied().unwrap_or(v)], cam) {
                assert!(finite(line.coords().as_slice()), "horizon not finite");
            }
        }
    }
});
