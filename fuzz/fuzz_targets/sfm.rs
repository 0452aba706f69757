//! Incremental structure from motion on arbitrary tracks: `TrackBuilder` on arbitrary joins,
//! `TrackSet::new_checked` on arbitrary rows, `reconstruct` with arbitrary intrinsics.
//! Contract: no panic; a view has a pose exactly when it is `Registered`; poses, points and
//! errors are finite; used observations belong to reconstructed points and registered views.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::camera::{Camera, Intrinsics};
use camgeom::nalgebra::{Point2, Point3};
use camgeom::sfm::{
    BundleScratch, IncrementalConfig, Observation, PointScratch, Scene, TrackBuilder, TrackSet,
    ViewResult, ViewState, Workspace, reconstruct,
};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Num, finite, pt2};

#[derive(Debug, Arbitrary)]
struct Input {
    views: u8,
    /// Rows: track length (the next observations), each `(view, pixel)`.
    rows: std::vec::Vec<(u8, std::vec::Vec<(u8, (Num, Num))>)>,
    joins: std::vec::Vec<(u16, u16)>,
    offsets: std::vec::Vec<u16>,
    k: [Num; 4],
    min_inliers: u8,
}

fuzz_target!(|inp: Input| {
    // Union-find on arbitrary joins and offsets.
    let nodes = inp
        .offsets
        .iter()
        .map(|&o| usize::from(o) % 64)
        .sum::<usize>()
        .min(256);
    let (mut parent, mut scratch, mut labels) =
        (vec![0u32; nodes], vec![0u32; nodes], vec![0u32; nodes]);
    if let Ok(mut b) = TrackBuilder::new(&mut parent, &mut scratch) {
        for &(x, y) in inp.joins.iter().take(512) {
            let _ = b.join(u32::from(x), u32::from(y));
        }
        let mut offsets = vec![0u32];
        for &o in &inp.offsets {
            let next = (*offsets.last().unwrap() + u32::from(o) % 64).min(nodes as u32);
            offsets.push(next);
        }
        if let Ok(n) = b.label(&offsets, &mut labels) {
            assert!(
                labels
                    .iter()
                    .all(|&l| l == camgeom::sfm::NO_TRACK || (l as usize) < n)
            );
        }
    }
    // Arbitrary tracks.
    let views = usize::from(inp.views % 8);
    let mut starts = vec![0u32];
    let mut obs: std::vec::Vec<Observation<f32>> = std::vec::Vec::new();
    for (_, row) in inp.rows.iter().take(200) {
        for &(v, p) in row.iter().take(8) {
            obs.push(Observation {
                view: u16::from(v % 9),
                pixel: pt2(p),
            });
        }
        starts.push(obs.len() as u32);
    }
    let Ok(set) = TrackSet::new_checked(&starts, &obs, views) else {
        return;
    };
    let [a, b, c, d] = inp.k.map(Num::get);
    let Ok(k) = Intrinsics::new(a, b, c, d) else {
        return;
    };
    let camera = Camera::pinhole(k);
    let mut config = IncrementalConfig::<f32>::default();
    config.min_initial_inliers = u32::from(inp.min_inliers % 64);
    config.min_registration_inliers = u32::from(inp.min_inliers % 32).max(4);
    config.bundle_iterations = 3;
    config.final_bundle_iterations = 3;
    let Ok(params) = config.check() else { return };
    let (nt, no) = (set.len(), obs.len());
    let mut poses = vec![None; views];
    let mut results = vec![ViewResult::<f32>::default(); views];
    let mut points: std::vec::Vec<Option<Point3<f32>>> = vec![None; nt];
    let mut used = vec![false; no];
    let mut normalized = vec![None; no];
    let mut covisibility = vec![0u32; views * views];
    let mut tried = vec![0u32; views];
    let mut counts = vec![0u32; views];
    let mut free = vec![true; views];
    let (mut first, mut second) = (vec![Point2::origin(); nt], vec![Point2::origin(); nt]);
    let mut world = vec![Point3::origin(); nt];
    let mut index = vec![0u32; nt];
    let (mut mask, mut mask2) = (vec![false; nt], vec![false; nt]);
    let mut angles = vec![0.0f32; nt];
    let mut system = vec![0.0f32; BundleScratch::<f32>::system_len(views)];
    let (mut rhs, mut gradient) = (vec![0.0f32; 6 * views], vec![0.0f32; 6 * views]);
    let mut bindex = vec![0u16; views];
    let mut trial = vec![None; views];
    let mut coupling = vec![Default::default(); no];
    let mut pscratch = vec![PointScratch::<f32>::default(); nt];
    let mut scene = Scene {
        poses: &mut poses,
        views: &mut results,
        points: &mut points,
        used: &mut used,
    };
    let mut ws = Workspace {
        normalized: &mut normalized,
        covisibility: &mut covisibility,
        tried: &mut tried,
        counts: &mut counts,
        first: &mut first,
        second: &mut second,
        world: &mut world,
        index: &mut index,
        mask: &mut mask,
        mask2: &mut mask2,
        angles: &mut angles,
        bundle: BundleScratch {
            system: &mut system,
            rhs: &mut rhs,
            gradient: &mut gradient,
            index: &mut bindex,
            free: &mut free,
            trial: &mut trial,
            coupling: &mut coupling,
            points: &mut pscratch,
        },
    };
    let Ok(r) = reconstruct(&camera, &set, &params, &mut scene, &mut ws) else {
        return;
    };
    assert!(r.registered <= views && r.rms_px.is_finite());
    for (p, v) in poses.iter().zip(&results) {
        assert_eq!(p.is_some(), v.state == ViewState::Registered, "{v:?}");
        if let Some(p) = p {
            assert!(finite(p.matrix().as_slice()), "pose not finite");
        }
        assert!(v.rms_px.is_finite());
    }
    for i in 0..nt {
        if let Some(x) = points[i] {
            assert!(finite(x.coords.as_slice()), "point not finite");
        }
        for (k, o) in set.track(i).iter().enumerate() {
            if used[set.range(i).start + k] {
                assert!(points[i].is_some(), "used observation of no point");
                assert!(
                    poses[usize::from(o.view)].is_some(),
                    "used observation of no view"
                );
            }
        }
    }
});
